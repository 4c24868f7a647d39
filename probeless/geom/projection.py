"""Camera matrices in the OpenGL clip-space convention, pure numpy.

Matrices are float64, row-major (``clip = M @ [x, y, z, 1]``); ``probeless.gl.programs.mat_bytes``
packs them for GLSL uniforms.
"""

from __future__ import annotations

import numpy as np


def clip_from_camera(K: np.ndarray, width: int, height: int, near: float, far: float) -> np.ndarray:
    """4x4 projection of an OpenCV pinhole (x right, y down, z forward) into GL clip space.

    Pixel (u, v) centres sit at integer coordinates; image row v = 0 lands on framebuffer row 0
    (the first row ``glReadPixels`` returns), so read-back arrays need no flip.
    """
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    return np.array([
        [2 * fx / width, K[0, 1] * 2 / width, 2 * (cx + 0.5) / width - 1, 0],
        [0, 2 * fy / height, 2 * (cy + 0.5) / height - 1, 0],
        [0, 0, (far + near) / (far - near), -2 * far * near / (far - near)],
        [0, 0, 1, 0],
    ], dtype=np.float64)


def view_from_world(rotation_rows: np.ndarray, position: np.ndarray) -> np.ndarray:
    """4x4 rigid map x -> R (x - position), R = the camera axes as rows in world coordinates."""
    m = np.eye(4)
    m[:3, :3] = rotation_rows
    m[:3, 3] = -rotation_rows @ np.asarray(position, dtype=np.float64)
    return m
