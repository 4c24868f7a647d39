"""Camera models (pinhole, omnidir, Kannala-Brandt, OCamCalib), calibration files, undistortion."""

from __future__ import annotations

from probeless.cameras.base import CameraModel
from probeless.cameras.kannala_brandt import KannalaBrandtModel
from probeless.cameras.ocam import OcamModel
from probeless.cameras.omnidir import OmnidirModel
from probeless.cameras.pinhole import PinholeModel
from probeless.errors import CalibrationError
from probeless.messages.sensor import CameraInfo

MODELS: dict[str, type[CameraModel]] = {
    "pinhole": PinholeModel,
    "omnidir": OmnidirModel,
    "kannala_brandt": KannalaBrandtModel,
    "ocam": OcamModel,
}


def model_from_info(info: CameraInfo) -> CameraModel:
    """The camera model described by a CameraInfo (any of the four CameraInfo models)."""
    cls = MODELS.get(info.model)
    if cls is None:
        raise CalibrationError(f"CameraInfo.model {info.model!r} has no camera model; expected one of {sorted(MODELS)}")
    return cls.from_camera_info(info)


__all__ = [
    "MODELS",
    "CameraModel",
    "KannalaBrandtModel",
    "OcamModel",
    "OmnidirModel",
    "PinholeModel",
    "model_from_info",
]
