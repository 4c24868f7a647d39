"""The synthetic RGB-D + fisheye rig: frame schedule, camera simulation and the messages it publishes.

Cameras behave like real LDR cameras: linear radiance x exposure, clipped to [0, 1], sRGB-encoded
to 8 bits. Depth is z along the optical axis in uint16 millimetres with additive Gaussian noise
(seeded per frame, so renders are reproducible), 0 where nothing was hit or beyond ``depth_max_m``.
Stamps are scene time in nanoseconds (t = 0 at the first RGB-D frame). A scene's ``sensor_effects``
block adds auto-exposure, white balance, vignetting, another response curve, Poisson-Gaussian noise,
light flicker and Kinect-like depth (probeless.scene.camera_sim, probeless.scene.depth_effects); its
``given`` block changes what the rig *tells* the pipeline (floorplan, fisheye_from_rgbd, fisheye
camera_info, fisheye clock), never what it renders (probeless.scene.given).

Outputs (topic = ``<node id>/<output>``): ``rgb``, ``depth``, ``rgbd/camera_info``, ``gt/rgbd_pose``
per RGB-D frame; ``fisheye``, ``fisheye/camera_info``, ``gt/fisheye_pose``, ``gt/fisheye_exposure``
(1x1 ``rgbf32`` Image: the per-channel multiplier exposure x white-balance gain that took this frame's
linear radiance to the signal fed to the response curve [-]) and, per virtual object, ``gt/envmap/<id>``
(linear HDR float16 cubemap at the object's centre, no sensor effect and no flicker) and
``gt/envmap_ldr/<id>`` (the same through the fisheye's current exposure, white balance, clipping and
response curve, without noise or vignetting: uint8, ``linear = False``) per fisheye frame;
``floorplan`` (the given one) then ``fisheye_from_rgbd`` (PoseStamped, frame "fisheye", child "rgbd":
the given extrinsics) once at the start.

Fisheye stamps: every fisheye-frame message (image, camera_info, gt/fisheye_pose, gt/fisheye_exposure)
carries the fisheye clock = true capture time + ``given.clock_offset_s``; gt/fisheye_pose holds the pose
at the true capture time. gt/envmap* and all RGB-D messages carry true times.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterator

import numpy as np

from probeless.messages.geometry import Floorplan, PoseStamped
from probeless.messages.header import Header, shift_stamp
from probeless.messages.lighting import Cubemap
from probeless.messages.sensor import CameraInfo, DepthImage, Image
from probeless.scene.build import build_geometry
from probeless.scene.camera_sim import CameraSim
from probeless.scene.depth_effects import kinect_depth
from probeless.scene.given import given_rig
from probeless.scene.sensor_effects import encode, flicker_factor, pinhole_cos_theta, response_lut
from probeless.scene.spec import Scene
from probeless.scene.trajectory import camera_pose

RGBD_FRAME, FISHEYE_FRAME = "rgbd", "fisheye"


_SRGB_LUT = response_lut(None)


def expose(radiance: np.ndarray, exposure: float) -> np.ndarray:
    """What an LDR camera records: ``radiance * exposure`` clipped, sRGB-encoded, uint8 (through a table)."""
    return encode(radiance, _SRGB_LUT, exposure)


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
        self.fisheye_from_rgbd = scene.fisheye_from_rgbd  # the truth, used to render
        n_windows = len(scene.windows)
        self._window_scale = np.ones(n_windows)
        self.given = given_rig(scene.given, scene.floorplan, scene.ceiling_height, scene.fisheye_from_rgbd,
                               self.fisheye.to_camera_info(FISHEYE_FRAME, 0))
        self.effects = fx = scene.sensor_effects
        self.rgbd_sim = self.fisheye_sim = None
        if fx is not None:
            c, K = scene.rgbd, scene.rgbd.K
            self.rgbd_sim = CameraSim(fx.rgbd, c.exposure, pinhole_cos_theta(c.width, c.height, K),
                                      (K[0, 2], K[1, 2]), None, (fx.seed, seed, 1))
            Kf = self.fisheye.K
            self.fisheye_sim = CameraSim(fx.fisheye, scene.fisheye.exposure, self.rays[..., 2],
                                         (Kf[0, 2], Kf[1, 2]), np.any(self.rays != 0, axis=-1), (fx.seed, seed, 2))

    def light_scale(self, t: float, camera: str | None = None) -> np.ndarray:
        """(L,) scale of every area light at time ``t``: ceiling lights by schedule (times the flicker averaged
        over ``camera``'s shutter when the scene has ``sensor_effects.flicker``), windows always on."""
        on = np.array([1.0 if light.is_on(t) else 0.0 for light in self.scene.lights])
        flicker = self.effects.flicker if self.effects is not None else None
        if flicker is not None and camera is not None:
            shutter = (self.effects.rgbd if camera == RGBD_FRAME else self.effects.fisheye).exposure_time_s
            on = on * flicker_factor(t, shutter, flicker.amplitude, flicker.frequency_hz, flicker.phase_deg)
        return np.concatenate([on, self._window_scale])

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
        radiance, z = self.renderer.render_pinhole(pose, cam.K, cam.width, cam.height,
                                                   self.light_scale(event.t, RGBD_FRAME))
        rng = np.random.default_rng((self.seed, event.index))
        if self.effects is None:
            return expose(radiance, cam.exposure), depth_to_mm(z, cam.depth_noise_m, cam.depth_max_m, rng), pose
        if self.effects.depth is not None:
            z = kinect_depth(z, cam.K, self.effects.depth, np.random.default_rng((self.effects.seed, self.seed, 3,
                                                                                  event.index)))
        rgb = self.rgbd_sim.record(radiance, event.t, event.index)
        return rgb, depth_to_mm(z, cam.depth_noise_m, cam.depth_max_m, rng), pose

    def render_fisheye(self, event: FrameEvent) -> tuple[np.ndarray, np.ndarray]:
        """(fisheye uint8 (H, W, 3), world_from_fisheye); black outside the field of view."""
        pose = self.fisheye_pose(event.t)
        radiance = self.renderer.render_rays(pose, self.rays, self.light_scale(event.t, FISHEYE_FRAME),
                                             self.fisheye_cube_size)
        if self.fisheye_sim is None:
            return expose(radiance, self.scene.fisheye.exposure), pose
        return self.fisheye_sim.record(radiance, event.t, event.index), pose

    def fisheye_gains(self) -> np.ndarray:
        """(3,) float32 exposure x white-balance multiplier of the last fisheye frame [-]."""
        if self.fisheye_sim is None:
            return np.full(3, self.scene.fisheye.exposure, np.float32)
        return self.fisheye_sim.gains()

    def fisheye_ldr(self, faces: np.ndarray) -> np.ndarray:
        """uint8 codes of linear radiance as the last fisheye frame's exposure, white balance and response curve
        record it, without noise or vignetting."""
        if self.fisheye_sim is None:
            return expose(faces, self.scene.fisheye.exposure)
        return self.fisheye_sim.ideal(faces)

    def render_envmap(self, position: np.ndarray, t: float) -> np.ndarray:
        """(6, S, S, 3) float32 linear radiance cubemap seen from ``position`` at time ``t``."""
        return self.renderer.render_cubemap(position, self.envmap_size, self.light_scale(t))

    def camera_infos(self) -> tuple[CameraInfo, CameraInfo]:
        """(RGB-D pinhole info, the given fisheye info) with stamp 0."""
        c = self.scene.rgbd
        rgbd = CameraInfo(Header(0, RGBD_FRAME), c.width, c.height, "pinhole", c.K)
        return rgbd, self.given.fisheye_info

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
        clock = stamp + int(round(self.given.clock_offset_s * 1e9))  # the fisheye's own clock
        yield "fisheye/camera_info", shift_stamp(fisheye_info, clock)
        yield "gt/fisheye_pose", PoseStamped(Header(clock, "world"), FISHEYE_FRAME, pose)
        yield "gt/fisheye_exposure", Image(Header(clock, FISHEYE_FRAME), self.fisheye_gains().reshape(1, 1, 3),
                                           "rgbf32")
        yield "fisheye", Image(Header(clock, FISHEYE_FRAME), image, "rgb8")
        if not self.envmaps:
            return
        for obj in self.scene.virtual_objects:
            faces = self.render_envmap(obj.position, event.t)
            header = Header(stamp, "world")
            yield f"gt/envmap/{obj.id}", Cubemap(header, obj.id, obj.position, faces.astype(np.float16))
            yield f"gt/envmap_ldr/{obj.id}", Cubemap(header, obj.id, obj.position, self.fisheye_ldr(faces),
                                                     linear=False)

    def floorplan(self) -> Floorplan:
        """The given floorplan message (stamp 0): the room's, or the ``given.floorplan`` perturbation of it."""
        return Floorplan(Header(0, "world"), self.given.floorplan, self.given.ceiling_height)

    def fisheye_from_rgbd_message(self) -> PoseStamped:
        """The given extrinsics (stamp 0): frame "fisheye", child "rgbd", p_fisheye = T @ p_rgbd."""
        return PoseStamped(Header(0, FISHEYE_FRAME), RGBD_FRAME, self.given.fisheye_from_rgbd)

    def release(self) -> None:
        self.renderer.release()

