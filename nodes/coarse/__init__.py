"""Coarse room model nodes: the atlas texturer and the brightness-change estimator (paper §4.3–4.6)."""
