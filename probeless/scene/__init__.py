"""Synthetic rooms: scene files, geometry, the OpenGL renderer and the RGB-D + fisheye rig."""
