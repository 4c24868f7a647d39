"""Image-based lighting nodes: the compositor that draws lit virtual objects into the RGB frame (paper §4.8)."""
