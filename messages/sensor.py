"""Sensor messages: colour images, depth images and camera calibration (like ROS sensor_msgs).

Images are row-major numpy arrays, row 0 at the top, column 0 at the left, in the optical frame
named by ``header.frame_id`` (x right, y down, z forward).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from probeless.errors import SchemaError
from probeless.messages.base import Message, array, message
from probeless.messages.header import Header

# encoding -> (dtype, channels). "f16"/"f32" are linear floats; integer encodings are as captured.
ENCODINGS: dict[str, tuple[str, int]] = {
    "mono8": ("uint8", 1), "rgb8": ("uint8", 3), "bgr8": ("uint8", 3),
    "rgba8": ("uint8", 4), "bgra8": ("uint8", 4),
    "mono16": ("uint16", 1), "rgb16": ("uint16", 3),
    "monof16": ("float16", 1), "rgbf16": ("float16", 3), "rgbaf16": ("float16", 4),
    "monof32": ("float32", 1), "rgbf32": ("float32", 3), "rgbaf32": ("float32", 4),
}

_ENCODING_DTYPES = {name: np.dtype(name) for name, _ in ENCODINGS.values()}  # dtype objects: .name is slow

CAMERA_MODELS = ("pinhole", "omnidir", "kannala_brandt", "ocam")
_D_LENGTHS = {"pinhole": (0, 4, 5, 8, 12, 14), "omnidir": (0, 4), "kannala_brandt": (0, 4), "ocam": (0,)}


@message("sensor/Image", version=1)
@dataclass(frozen=True)
class Image(Message):
    """A colour or mono image; always rank 3 (mono has c=1). ``encoding`` must match dtype and c."""

    header: Header      # stamp = exposure time; frame_id = the camera's optical frame
    # pixels [row, col, channel], optical frame
    data: np.ndarray = array(("uint8", "uint16", "float16", "float32"), ("h", "w", "c"))
    encoding: str = "rgb8"  # one of ENCODINGS, e.g. rgb8, bgr8, mono8, mono16, rgbf32 [-]

    def validate(self) -> None:
        want = ENCODINGS.get(self.encoding)
        if want is None:
            raise SchemaError(f"Image.encoding: unknown encoding {self.encoding!r}, "
                              f"expected one of {sorted(ENCODINGS)}")
        dtype, channels = want
        if self.data.dtype != _ENCODING_DTYPES[dtype] or self.data.shape[2] != channels:
            raise SchemaError(f"Image.encoding: {self.encoding!r} needs {dtype} with {channels} channel(s), "
                              f"Image.data is {self.data.dtype.name} with {self.data.shape[2]}")

    @property
    def height(self) -> int:
        """Rows [px]."""
        return self.data.shape[0]

    @property
    def width(self) -> int:
        """Columns [px]."""
        return self.data.shape[1]

    @property
    def channels(self) -> int:
        """Channels per pixel [count]."""
        return self.data.shape[2]


@message("sensor/DepthImage", version=1)
@dataclass(frozen=True)
class DepthImage(Message):
    """Depth along the optical axis (z, not ray length). 0 (and NaN for float32) = no measurement."""

    header: Header      # stamp = exposure time; frame_id = the depth camera's optical frame
    data: np.ndarray = array(("uint16", "float32"), ("h", "w"))  # depth [depth units = 1/depth_scale m], optical frame
    depth_scale: float  # depth units per metre: 1000.0 for uint16 millimetres, 1.0 for float32 metres [1/m]

    def validate(self) -> None:
        if not (np.isfinite(self.depth_scale) and self.depth_scale > 0):
            raise SchemaError(f"DepthImage.depth_scale: must be finite and > 0, got {self.depth_scale}")

    def metres(self) -> np.ndarray:
        """Depth in metres as float32; invalid pixels are 0."""
        d = self.data.astype(np.float32) / np.float32(self.depth_scale)
        return np.nan_to_num(d, nan=0.0, posinf=0.0, neginf=0.0)


@message("sensor/CameraInfo", version=1)
@dataclass(frozen=True)
class CameraInfo(Message):
    """Intrinsic calibration of one camera. Which fields are used depends on ``model``:

    * ``pinhole``: K and OpenCV distortion D = (k1, k2, p1, p2[, k3[, k4, k5, k6[, s1..s4[, tx, ty]]]]),
      as cv2.projectPoints / cv2.undistort; len(D) in {0, 4, 5, 8, 12, 14}.
    * ``omnidir``: Mei unified sphere model as cv2.omnidir: K, xi, D = (k1, k2, p1, p2) or empty.
    * ``kannala_brandt``: equidistant fisheye as cv2.fisheye: K, D = (k1, k2, k3, k4) or empty.
    * ``ocam``: Scaramuzza OCamCalib model; the ocam_* fields are copied verbatim from OCamCalib's
      calib_results.txt (its own conventions: poly/invpoly in ascending powers, centre (xc, yc) =
      (row, col), affine (c, d, e)); D must be empty. K is a nominal pinhole for rectified views.
    """

    header: Header      # frame_id = the camera's optical frame (x right, y down, z forward)
    width: int          # image width [px]
    height: int         # image height [px]
    model: str          # pinhole | omnidir | kannala_brandt | ocam
    K: np.ndarray = array("float64", (3, 3))  # camera matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] [px]
    # distortion coefficients, per model [-]
    D: np.ndarray = array("float64", (None,), default_factory=lambda: np.zeros(0))
    xi: float = 0.0     # Mei sphere offset, omnidir only [unit sphere radii]
    # cam2world polynomial a0, a1, ... (a_k in [px^(1-k)])
    ocam_poly: np.ndarray = array("float64", (None,), default_factory=lambda: np.zeros(0))
    # world2cam polynomial, ascending (b_k in [px/rad^k])
    ocam_invpoly: np.ndarray = array("float64", (None,), default_factory=lambda: np.zeros(0))
    # (c, d, e) stretch [-]
    ocam_affine: np.ndarray = array("float64", (3,), default_factory=lambda: np.array([1.0, 0.0, 0.0]))
    ocam_center: np.ndarray = array("float64", (2,), default_factory=lambda: np.zeros(2))  # (xc, yc) = (row, col) [px]

    def validate(self) -> None:
        if self.width <= 0 or self.height <= 0:
            raise SchemaError(f"CameraInfo.width/height: must be > 0, got {self.width}x{self.height}")
        if self.model not in CAMERA_MODELS:
            raise SchemaError(f"CameraInfo.model: unknown model {self.model!r}, expected one of {CAMERA_MODELS}")
        K = self.K
        if not np.all(np.isfinite(K)) or K[0, 0] <= 0 or K[1, 1] <= 0 or not np.allclose(K[2], (0, 0, 1)):
            raise SchemaError("CameraInfo.K: must be finite with fx, fy > 0 and last row [0, 0, 1]")
        if len(self.D) not in _D_LENGTHS[self.model]:
            raise SchemaError(f"CameraInfo.D: {len(self.D)} coefficients invalid for model {self.model!r}, "
                              f"expected one of {_D_LENGTHS[self.model]}")
        if not np.isfinite(self.xi) or self.xi < 0 or (self.xi != 0 and self.model != "omnidir"):
            raise SchemaError(f"CameraInfo.xi: must be finite, >= 0 and only non-zero for omnidir, got {self.xi}")
        if self.model == "ocam" and (len(self.ocam_poly) == 0 or len(self.ocam_invpoly) == 0):
            raise SchemaError("CameraInfo.ocam_poly: ocam model needs non-empty ocam_poly and ocam_invpoly")


@message("sensor/Imu", version=1)
@dataclass(frozen=True)
class Imu(Message):
    """One inertial sample, as ROS ``sensor_msgs/Imu`` carries it (kept as recorded, not used by the pipeline).

    A covariance whose first element is -1 means "this quantity is not measured" (ROS convention);
    all zeros means "unknown covariance".
    """

    header: Header      # stamp = sample time; frame_id = the IMU's frame
    orientation: np.ndarray = array("float64", (4,))  # quaternion [x, y, z, w] of frame_id in its reference [-]
    orientation_covariance: np.ndarray = array("float64", (9,))  # row-major 3x3 about x, y, z [rad²]
    angular_velocity: np.ndarray = array("float64", (3,))  # about x, y, z of frame_id [rad/s]
    angular_velocity_covariance: np.ndarray = array("float64", (9,))  # row-major 3x3 [(rad/s)²]
    linear_acceleration: np.ndarray = array("float64", (3,))  # along x, y, z of frame_id, gravity included [m/s²]
    linear_acceleration_covariance: np.ndarray = array("float64", (9,))  # row-major 3x3 [(m/s²)²]

    def validate(self) -> None:
        for name in ("angular_velocity", "linear_acceleration"):
            if not np.all(np.isfinite(getattr(self, name))):
                raise SchemaError(f"Imu.{name}: contains NaN or inf")
