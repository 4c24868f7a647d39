"""Coarse room model: floorplan prism, atlas texturing from the fisheye, occlusion, inpainting, brightness."""
