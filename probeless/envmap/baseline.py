"""The paper's baseline environment map (§5.3): the fisheye image pasted onto the sphere of directions.

Every frame, each cube texel's world direction ``d`` is rotated into the fisheye's frame
(``R^T d`` with ``R`` the rotation of ``world_from_fisheye``; the translation is ignored, i.e. the
room is assumed infinitely far away), projected with the runtime fisheye model and, where it lies in
the field of view, overwritten with the bilinear sample of the image there. Nothing is cleared
between frames: texels keep the value of the last frame that saw them, so the map builds up as the
room is observed; never-seen texels stay neutral grey (sRGB code 128, as the paper's coarse texture starts;
:meth:`BaselineMap.observed` False).

Because translation is ignored, the map is the same for every virtual object. The faces are camera
LDR colour (sRGB-encoded fisheye output / 255), the units of the coarse atlas. For the paper's
"baseline + dense model", draw the dense model over :attr:`BaselineMap.faces` (cubemap renderer).
"""

from __future__ import annotations

import numpy as np

from probeless.cameras.base import CameraModel
from probeless.coarse.atlas import UNSEEN_GREY
from probeless.coarse.project import project_columns, sample_columns
from probeless.errors import ProbelessError, SchemaError
from probeless.geom.cube import cube_directions
from probeless.messages.header import Header
from probeless.messages.lighting import Cubemap


def rotation_only(world_from_fisheye: np.ndarray) -> np.ndarray:
    """``world_from_fisheye`` with its translation zeroed (4, 4) float64."""
    T = np.array(world_from_fisheye, dtype=np.float64)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise ProbelessError(f"baseline envmap: world_from_fisheye must be a finite 4x4 matrix, got shape {T.shape}")
    T[:3, 3] = 0.0
    return T


class BaselineMap:
    """Accumulating fisheye-to-cubemap map; see the module doc."""

    def __init__(self, face_size: int, fisheye_model: CameraModel, fov_deg: float):
        if face_size < 1:
            raise ProbelessError(f"baseline envmap: face_size must be >= 1, got {face_size}")
        if not 0 < fov_deg < 360:
            raise ProbelessError(f"baseline envmap: fov_deg must be in (0, 360), got {fov_deg}")
        self.size, self.model, self.fov_deg = int(face_size), fisheye_model, float(fov_deg)
        # [face, row, col] order, built once: ~0.4 M texels at 256^2 faces
        self.directions = cube_directions(self.size).reshape(-1, 3)
        self.faces = np.full((6, self.size, self.size, 3), UNSEEN_GREY, np.float32)  # camera LDR 0..1
        self._observed = np.zeros((6, self.size, self.size), bool)
        self.frames = 0

    def update(self, image: np.ndarray, world_from_fisheye: np.ndarray) -> int:
        """Paste one fisheye frame (uint8 (H, W, 3), runtime model) at its pose; returns texels written."""
        m = self.model
        if image.dtype != np.uint8 or image.shape != (m.height, m.width, 3):
            raise SchemaError(f"baseline envmap: fisheye image must be uint8 ({m.height}, {m.width}, 3) for the "
                              f"camera model, got {image.dtype} {image.shape}")
        u, v, in_view = project_columns(self.directions, m, rotation_only(world_from_fisheye), self.fov_deg)
        idx = np.flatnonzero(in_view)
        self.faces.reshape(-1, 3)[idx] = sample_columns(image, u[idx], v[idx])
        self._observed.reshape(-1)[idx] = True
        self.frames += 1
        return len(idx)

    def reset(self) -> None:
        """Forget everything observed."""
        self.faces[:] = UNSEEN_GREY
        self._observed[:] = False
        self.frames = 0

    def observed(self) -> np.ndarray:
        """(6, S, S) bool copy: texels some fisheye frame has covered."""
        return self._observed.copy()

    def faces_as(self, dtype: str = "uint8", alpha: bool = False) -> np.ndarray:
        """The faces as ``uint8`` (0..255, rounded) or ``float16``/``float32`` (0..1); A = observed when ``alpha``."""
        if dtype == "uint8":
            out = np.round(self.faces * 255.0).astype(np.uint8)
            a = self._observed.astype(np.uint8) * np.uint8(255)
        elif dtype in ("float16", "float32"):
            out = self.faces.astype(dtype)
            a = self._observed.astype(dtype)
        else:
            raise ProbelessError(f"baseline envmap: dtype must be uint8, float16 or float32, got {dtype!r}")
        return np.concatenate([out, a[..., None]], axis=-1) if alpha else out

    def cubemap(self, header: Header, object_id: str, position: np.ndarray, dtype: str = "uint8",
                alpha: bool = False) -> Cubemap:
        """The map as a display-referred (``linear=False``) Cubemap message for one object."""
        return Cubemap(header, object_id, np.asarray(position, np.float64), self.faces_as(dtype, alpha), linear=False)
