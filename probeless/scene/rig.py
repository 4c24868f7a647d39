"""The synthetic RGB-D + fisheye rig: frame schedule, camera simulation and the messages it publishes.

Cameras behave like real LDR cameras: linear radiance x exposure, clipped to [0, 1], sRGB-encoded
to 8 bits. Depth is z along the optical axis in uint16 millimetres with additive Gaussian noise
(seeded per frame, so renders are reproducible), 0 where nothing was hit or beyond ``depth_max_m``.
Stamps are scene time in nanoseconds (t = 0 at the first RGB-D frame).

Outputs (topic = ``<node id>/<output>``): ``rgb``, ``depth``, ``rgbd/camera_info``, ``gt/rgbd_pose``
per RGB-D frame; ``fisheye``, ``fisheye/camera_info``, ``gt/fisheye_pose`` and, per virtual object,
``gt/envmap/<id>`` (linear HDR float16 cubemap at the object's centre) and ``gt/envmap_ldr/<id>``
(the same after the fisheye's exposure, clipping and sRGB encoding: uint8, ``linear = False``) per
fisheye frame; ``floorplan`` once at the start.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterator

import numpy as np

from probeless.color import linear_to_srgb
from probeless.messages.geometry import Floorplan, PoseStamped
from probeless.messages.header import Header, shift_stamp
from probeless.messages.lighting import Cubemap
from probeless.messages.sensor import CameraInfo, DepthImage, Image
from probeless.scene.build import build_geometry
from probeless.scene.spec import Scene
from probeless.scene.trajectory import camera_pose

RGBD_FRAME, FISHEYE_FRAME = "rgbd", "fisheye"


_SRGB_STEPS = 65535
_SRGB_LUT = np.round(linear_to_srgb(np.arange(_SRGB_STEPS + 1) / _SRGB_STEPS) * 255.0).astype(np.uint8)


def expose(radiance: np.ndarray, exposure: float) -> np.ndarray:
    """What an LDR camera records: ``radiance * exposure`` clipped, sRGB-encoded, uint8.

    Encoded through a 65536-entry table (linear steps of 1.5e-5; at most one code from the exact
    rounding), several times faster than evaluating the sRGB power law per pixel.
    """
    scaled = np.nan_to_num(radiance * np.float32(exposure * _SRGB_STEPS), nan=0.0)
    return _SRGB_LUT[np.clip(scaled + 0.5, 0, _SRGB_STEPS).astype(np.uint16)]


def depth_to_mm(z: np.ndarray, noise_m: float, max_m: float, rng: np.random.Generator) -> np.ndarray:
    """uint16 millimetres from z [m] with additive Gaussian noise; 0 where invalid or beyond ``max_m``."""
    valid = (z > 0) & (z <= max_m)
    noisy = z + rng.normal(0.0, noise_m, z.shape) if noise_m > 0 else z
    mm = np.where(valid, np.round(noisy * 1000.0), 0)
    return np.clip(mm, 0, 65535).astype(np.uint16)


@dataclass(frozen=True)
class FrameEvent:
    """One frame to render: camera kind, its index on that camera, scene time [s]."""

    kind: str
    index: int
    t: float

    @property
    def stamp_ns(self) -> int:
        return int(round(self.t * 1e9))


def frame_schedule(scene: Scene, duration: float | None = None) -> list[FrameEvent]:
    """Every RGB-D and fisheye frame in [0, duration] in time order (RGB-D first on ties)."""
    end = scene.duration if duration is None else duration
    events = []
    for kind, fps, offset in ((RGBD_FRAME, scene.rgbd.fps, 0.0),
                              (FISHEYE_FRAME, scene.fisheye.fps, scene.fisheye.time_offset_s)):
        n = int(np.floor((end - offset) * fps + 1e-9)) + 1 if end >= offset else 0
        events += [FrameEvent(kind, i, offset + i / fps) for i in range(max(0, n)) if offset + i / fps >= 0]
    return sorted(events, key=lambda e: (e.t, e.kind != RGBD_FRAME))


def fisheye_model(scene: Scene):
    """The fisheye's camera model (an ideal ``fov_deg`` model filling the image circle)."""
    from probeless.cameras.kannala_brandt import KannalaBrandtModel
    from probeless.cameras.omnidir import OmnidirModel

    f = scene.fisheye
    if f.model == "omnidir":
        return OmnidirModel.from_fov(f.width, f.height, f.fov_deg, xi=f.xi)
    return KannalaBrandtModel.from_fov(f.width, f.height, f.fov_deg)


def fisheye_rays(model, fov_deg: float) -> np.ndarray:
    """(H, W, 3) float32 unit rays of every fisheye pixel in its camera frame; 0 outside the field of view."""
    v, u = np.mgrid[0:model.height, 0:model.width].astype(np.float64)
    rays, valid = model.unproject(np.stack([u.ravel(), v.ravel()], axis=1))
    valid &= rays[:, 2] >= np.cos(np.radians(fov_deg) / 2) - 1e-9
    rays = np.where(valid[:, None], rays, 0.0)
    return rays.reshape(model.height, model.width, 3).astype(np.float32)


class Rig:
    """Renders the scene's cameras and ground truth; :meth:`messages` yields what the rig publishes."""

    def __init__(self, scene: Scene, *, renderer=None, envmap_size: int = 64, fisheye_cube_size: int = 512,
                 seed: int = 0, envmaps: bool = True):
        from probeless.scene.render import SceneRenderer

        self.scene = scene
        self.renderer = renderer or SceneRenderer(build_geometry(scene))
        self.envmap_size, self.fisheye_cube_size = envmap_size, fisheye_cube_size
        self.seed, self.envmaps = seed, envmaps
        self.fisheye = fisheye_model(scene)
        self.rays = fisheye_rays(self.fisheye, scene.fisheye.fov_deg)
        self.fisheye_from_rgbd = scene.fisheye_from_rgbd
        n_windows = len(scene.windows)
        self._window_scale = np.ones(n_windows)

    def light_scale(self, t: float) -> np.ndarray:
        """(L,) on/off scale of every area light at time ``t``: ceiling lights by schedule, windows always on."""
        return np.concatenate([[1.0 if light.is_on(t) else 0.0 for light in self.scene.lights], self._window_scale])

    def rgbd_pose(self, t: float) -> np.ndarray:
        """world_from_rgbd (4, 4) at ``t``."""
        return camera_pose(self.scene.keyframes, t)

    def fisheye_pose(self, t: float) -> np.ndarray:
        """world_from_fisheye (4, 4) at ``t`` (the rig is rigid)."""
        return self.rgbd_pose(t) @ np.linalg.inv(self.fisheye_from_rgbd)

    def render_rgbd(self, event: FrameEvent) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(rgb uint8 (H, W, 3), depth uint16 mm (H, W), world_from_rgbd) of an RGB-D frame."""
        cam = self.scene.rgbd
        pose = self.rgbd_pose(event.t)
        radiance, z = self.renderer.render_pinhole(pose, cam.K, cam.width, cam.height, self.light_scale(event.t))
        rng = np.random.default_rng((self.seed, event.index))
        return expose(radiance, cam.exposure), depth_to_mm(z, cam.depth_noise_m, cam.depth_max_m, rng), pose

    def render_fisheye(self, event: FrameEvent) -> tuple[np.ndarray, np.ndarray]:
        """(fisheye uint8 (H, W, 3), world_from_fisheye); black outside the field of view."""
        pose = self.fisheye_pose(event.t)
        radiance = self.renderer.render_rays(pose, self.rays, self.light_scale(event.t), self.fisheye_cube_size)
        return expose(radiance, self.scene.fisheye.exposure), pose

    def render_envmap(self, position: np.ndarray, t: float) -> np.ndarray:
        """(6, S, S, 3) float32 linear radiance cubemap seen from ``position`` at time ``t``."""
        return self.renderer.render_cubemap(position, self.envmap_size, self.light_scale(t))

    def camera_infos(self) -> tuple[CameraInfo, CameraInfo]:
        """(RGB-D pinhole info, fisheye info) with stamp 0."""
        c = self.scene.rgbd
        rgbd = CameraInfo(Header(0, RGBD_FRAME), c.width, c.height, "pinhole", c.K)
        return rgbd, self.fisheye.to_camera_info(FISHEYE_FRAME, 0)

    def messages(self, event: FrameEvent) -> Iterator[tuple[str, object]]:
        """(output, message) pairs of one frame event, in publishing order."""
        stamp = event.stamp_ns
        rgbd_info, fisheye_info = self.camera_infos()
        if event.kind == RGBD_FRAME:
            rgb, depth, pose = self.render_rgbd(event)
            yield "rgbd/camera_info", shift_stamp(rgbd_info, stamp)
            yield "gt/rgbd_pose", PoseStamped(Header(stamp, "world"), RGBD_FRAME, pose)
            yield "rgb", Image(Header(stamp, RGBD_FRAME), rgb, "rgb8")
            yield "depth", DepthImage(Header(stamp, RGBD_FRAME), depth, 1000.0)
            return
        image, pose = self.render_fisheye(event)
        yield "fisheye/camera_info", shift_stamp(fisheye_info, stamp)
        yield "gt/fisheye_pose", PoseStamped(Header(stamp, "world"), FISHEYE_FRAME, pose)
        yield "fisheye", Image(Header(stamp, FISHEYE_FRAME), image, "rgb8")
        if not self.envmaps:
            return
        for obj in self.scene.virtual_objects:
            faces = self.render_envmap(obj.position, event.t)
            header = Header(stamp, "world")
            yield f"gt/envmap/{obj.id}", Cubemap(header, obj.id, obj.position, faces.astype(np.float16))
            ldr = expose(faces, self.scene.fisheye.exposure)
            yield f"gt/envmap_ldr/{obj.id}", Cubemap(header, obj.id, obj.position, ldr, linear=False)

    def floorplan(self) -> Floorplan:
        """The room's floorplan message (stamp 0)."""
        return Floorplan(Header(0, "world"), self.scene.floorplan, self.scene.ceiling_height)

    def release(self) -> None:
        self.renderer.release()

