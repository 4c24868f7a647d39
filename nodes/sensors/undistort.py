"""Fisheye undistortion node: resample raw frames of any calibrated model into the runtime model.

The runtime model is an ideal (distortion-free) omnidir (Mei / Ying-Hu unified sphere) camera of
``fov_deg`` and ``xi`` whose field-of-view circle fits the ``width`` x ``height`` output, or an
equirectangular "longlat" image in the camera frame (see :mod:`probeless.cameras.undistort` for its
axes). A look-up table is built once per distinct input CameraInfo and applied with cv2.remap.

Outputs: ``image`` (same header, encoding and channels as the input) and, for the omnidir target
only, ``camera_info`` (the runtime model, stamped like the input CameraInfo, published once per
input CameraInfo). No CameraInfo model describes an equirectangular image, so a longlat target
publishes no camera_info: its geometry is fully given by the node's width/height parameters.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from probeless.cameras import model_from_info
from probeless.cameras.base import CameraModel
from probeless.cameras.omnidir import OmnidirModel
from probeless.cameras.undistort import INTERPOLATIONS, LongLat, build_lut, remap
from probeless.errors import CalibrationError
from probeless.messages.base import messages_equal
from probeless.messages.header import Header
from probeless.messages.sensor import CameraInfo, Image
from probeless.runtime import Node, param


def target_model(params) -> OmnidirModel | LongLat:
    """The destination geometry described by the node parameters."""
    if params.target == "longlat":
        return LongLat(params.width, params.height, params.lon_span_deg, params.lat_span_deg)
    return OmnidirModel.from_fov(params.width, params.height, params.fov_deg, params.xi)


def _target_problem(fov_deg: float, params) -> str | None:
    """fov_deg's rule against xi (a param check): the omnidir target model exists for them."""
    try:
        target_model(params)
    except CalibrationError as exc:
        return str(exc)
    return None


def same_calibration(a: CameraInfo, b: CameraInfo) -> bool:
    """Equal intrinsics (the header is ignored: a re-stamped CameraInfo needs no new LUT)."""
    return messages_equal(replace(a, header=Header(0)), replace(b, header=Header(0)))


class FisheyeUndistort(Node):
    """Raw fisheye ``image`` + its ``camera_info`` -> runtime-model ``image`` (+ ``camera_info``)."""

    INPUTS = {"image": Image, "camera_info": CameraInfo}
    OUTPUTS = {"image": Image, "camera_info": CameraInfo}

    @dataclass(frozen=True)
    class Params:
        target: str = param("omnidir", choices=("omnidir", "longlat"),
                            doc="omnidir = the runtime unified-sphere model; longlat = equirectangular")
        width: int = param(1024, min=1, max=8192, doc="output width [px]")
        height: int = param(1024, min=1, max=8192, doc="output height [px]")
        fov_deg: float = param(185.0, min=1.0, max=359.0, check=_target_problem,
                               doc="omnidir target: field of view fitting the image [deg] (within xi's domain)")
        xi: float = param(1.0, min=0.0, max=10.0, doc="omnidir target: Mei sphere offset xi [-]")
        lon_span_deg: float = param(360.0, min=1.0, max=360.0, doc="longlat target: longitude span [deg]")
        lat_span_deg: float = param(180.0, min=1.0, max=180.0, doc="longlat target: latitude span [deg]")
        interpolation: str = param("linear", choices=tuple(INTERPOLATIONS), doc="cv2.remap interpolation")

    def setup(self) -> None:
        self.target = target_model(self.params)  # fov_deg / xi checked at load
        self.info: CameraInfo | None = None
        self.source: CameraModel | None = None
        self.lut: tuple[np.ndarray, np.ndarray] | None = None
        self.lut_builds = 0
        self.dropped = 0

    def on_input(self, name: str, msg) -> None:
        if name == "camera_info":
            self._on_camera_info(msg)
        else:
            self._on_image(msg)

    def _on_camera_info(self, info: CameraInfo) -> None:
        if self.info is None or not same_calibration(self.info, info):
            self.source = model_from_info(info)
            with self.ctx.timed("build_lut"):
                self.lut = build_lut(self.source, self.target)
            self.lut_builds += 1
            self.ctx.log.info("built undistortion LUT #%d: %s %dx%d -> %s %dx%d", self.lut_builds, info.model,
                              info.width, info.height, self.params.target, self.params.width, self.params.height)
        self.info = info
        if isinstance(self.target, OmnidirModel):
            self.ctx.publish("camera_info", self.target.to_camera_info(info.header.frame_id, info.header.stamp_ns))

    def _on_image(self, image: Image) -> None:
        if self.lut is None:
            if self.dropped == 0:
                self.ctx.log.warning("dropping images until the first camera_info arrives")
            self.dropped += 1
            return
        if (image.width, image.height) != (self.info.width, self.info.height):
            raise CalibrationError(f"image {image.width}x{image.height} does not match camera_info "
                                   f"{self.info.width}x{self.info.height} (frame {image.header.frame_id!r})")
        with self.ctx.timed("remap"):
            data = remap(image.data, self.lut, self.params.interpolation)
        self.ctx.publish("image", Image(image.header, data, image.encoding))

    def close(self) -> None:
        if self.dropped:
            self.ctx.log.warning("dropped %d image(s) received before the first camera_info", self.dropped)
