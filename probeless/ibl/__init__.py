"""Image-based lighting of virtual objects and compositing into the camera image (paper §4.8)."""
