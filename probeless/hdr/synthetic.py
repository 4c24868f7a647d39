"""Ground truth for the HDR expansion (paper 001, §6.2) made from the synthetic rooms of :mod:`probeless.scene`.

Where the truth comes from: the rig's RGB-D camera (:class:`probeless.scene.rig.Rig`) records
``expose(radiance, exposure)`` (clipped, sRGB-encoded) from the linear radiance that
:meth:`probeless.scene.render.SceneRenderer.render_pinhole` returns before any exposure, clipping or
encoding. :func:`synthetic_case` calls that same renderer (the rig's own ``rig.renderer``) at ``frames``
poses spread evenly over the trajectory (:meth:`Rig.rgbd_pose`), with the rig's intrinsics scaled by
``scale`` (e.g. 640 x 480 -> 160 x 120), and back-projects every pixel with its exact (noise-free) depth.
Each point's ``true_radiance`` is the unclipped linear radiance of its pixel; points are then merged in a
``voxel`` [m] grid (position and radiance averaged per voxel, so the truth is the voxel's mean
radiance), which keeps N manageable (~20-150k). All frames use one lighting state: the lights as they are
at the end of the trajectory (``t = scene.duration``; the light of ``light_switch`` is then on).

``ldr_colors = clip(exposure * true_radiance, 0, 1)`` (Eq. 1, float32, computed exactly so; a scene with sensor
effects gets its RGB-D camera's white balance, noise and 8-bit response instead, :func:`scanner_ldr`). The HDR
photo is a linear pinhole render (:meth:`SceneRenderer.render_pinhole`, ``photo_fov_deg`` horizontal,
``photo_size`` (width, height)) of the part of the room the trajectory looks at: from the mean of the
keyframe positions plus ``photo_offset`` (default 0.35 m up, so on no RGB-D frame's or expansion view's
viewpoint) towards, with ``photo_target="overexposed"`` (default), the centroid of the cloud's over-exposed
points (:func:`probeless.hdr.transfer.overexposed`; as a photographer aims the HDR photo at the bright
parts), or with ``"look-at"`` (or when nothing is over-exposed) the mean of the keyframes' look-at points,
or a given world point (3 numbers [m], e.g. the coarse model's over-exposed texels' centroid);
times the unknown ``photo_exposure``. The ceiling lamps are in no RGB-D frame of the shipped scenes, so
the over-exposed points are the windows and the lamp-lit surfaces. Everything is deterministic
(no noise, no random draw; ``seed`` is kept for the interface and only recorded).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from probeless.errors import HdrError


@dataclasses.dataclass(frozen=True, eq=False)
class SyntheticCase:
    """``points`` (N, 3) float32 [m, world]; ``true_radiance`` (N, 3) float32 linear, unclipped [scene
    radiance units]; ``ldr_colors`` (N, 3) float32 = clip(exposure * true_radiance, 0, 1); ``photo_hdr``
    (H, W, 3) float32 linear radiance times ``photo_exposure``; ``object_position`` (3,) [m] (the
    scene's first virtual object); ``exposure``, ``photo_exposure``, ``photo_position`` and the ``scene``
    name; ``photo_K`` / ``photo_world_from_camera``: the photo's true pinhole (an oracle). Cloud units
    (:mod:`probeless.hdr.expand`) are ``exposure * true_radiance``."""

    points: np.ndarray
    true_radiance: np.ndarray
    ldr_colors: np.ndarray
    photo_hdr: np.ndarray
    object_position: np.ndarray
    exposure: float
    photo_exposure: float
    photo_position: np.ndarray
    scene: str
    photo_K: np.ndarray | None = None
    photo_world_from_camera: np.ndarray | None = None

    @property
    def truth_cloud_units(self) -> np.ndarray:
        """(N, 3) float32: the true radiance in the LDR colours' linear scale (``exposure * true_radiance``)."""
        return (np.float32(self.exposure) * self.true_radiance).astype(np.float32)


def voxel_merge(points: np.ndarray, values: np.ndarray, voxel: float) -> tuple[np.ndarray, np.ndarray]:
    """(points, values) averaged per ``voxel`` [m] grid cell, in the order of the sorted cell keys."""
    keys = np.floor(points / voxel).astype(np.int64)
    _, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    p = np.zeros((len(counts), 3))
    v = np.zeros((len(counts), values.shape[1]))
    np.add.at(p, inverse, points)
    np.add.at(v, inverse, values)
    return p / counts[:, None], v / counts[:, None]


def scanner_ldr(truth: np.ndarray, exposure: float, effects=None) -> np.ndarray:
    """(N, 3) float32 linear LDR colours of the cloud: ``clip(exposure * truth, 0, 1)`` exactly (Eq. 1) for an
    ideal scene; for a scene with ``sensor_effects`` (the ``*_realistic`` ones) its RGB-D camera's white-balance
    gains, Poisson-Gaussian noise (seeded) and response curve to 8-bit codes, which the pipeline reads back as
    sRGB (so a gamma-2.2 response is decoded slightly wrong, as a real scan would be)."""
    from probeless.color import from_srgb8
    from probeless.scene.sensor_effects import encode, poisson_gaussian, response_lut

    x = np.float32(exposure) * np.asarray(truth, np.float32)
    cam = None if effects is None else effects.rgbd
    if cam is None:
        return np.clip(x, 0.0, 1.0).astype(np.float32)
    if cam.wb_gains is not None:
        x = x * np.asarray(cam.wb_gains, np.float32)
    if cam.noise is not None:
        x = poisson_gaussian(x, cam.noise, np.random.default_rng(effects.seed))
    return from_srgb8(encode(np.clip(x, 0.0, 1.0), response_lut(cam.gamma))).astype(np.float32)


def synthetic_case(scene_path: str | Path, *, frames: int = 8, scale: float = 0.25, voxel: float = 0.02,
                   exposure: float = 1.0, photo_exposure: float = 0.37, photo_size=(320, 240),
                   photo_fov_deg: float = 100.0, photo_offset=(0.0, 0.0, 0.35),
                   photo_target="overexposed", seed: int = 0) -> SyntheticCase:
    """The :class:`SyntheticCase` of a scene YAML (module docstring: where the truth comes from)."""
    from probeless.hdr.transfer import overexposed
    from probeless.hdr.views import camera_looking_at
    from probeless.scene.parse import load_scene
    from probeless.scene.rig import Rig

    aim = None
    if not isinstance(photo_target, str):
        aim = np.asarray(photo_target, np.float64)
        if aim.shape != (3,) or not np.isfinite(aim).all():
            raise HdrError(f"synthetic_case: photo_target point must be 3 finite numbers, got {photo_target!r}")
    elif photo_target not in ("overexposed", "look-at"):
        raise HdrError(f"synthetic_case: photo_target must be 'overexposed', 'look-at' or a point, "
                       f"got {photo_target!r}")
    if frames < 1 or not 0 < scale <= 1 or voxel <= 0 or exposure <= 0 or photo_exposure <= 0:
        raise HdrError("synthetic_case: frames >= 1, 0 < scale <= 1, voxel, exposure, photo_exposure > 0")
    scene = load_scene(scene_path)
    if not scene.virtual_objects:
        raise HdrError(f"synthetic_case: scene {scene.name!r} has no virtual object")
    cam = scene.rgbd
    w, h = max(8, int(round(cam.width * scale))), max(8, int(round(cam.height * scale)))
    sx, sy = w / cam.width, h / cam.height
    K = np.asarray(cam.K, np.float64)
    K = np.array([[K[0, 0] * sx, 0, (K[0, 2] + 0.5) * sx - 0.5], [0, K[1, 1] * sy, (K[1, 2] + 0.5) * sy - 0.5],
                  [0, 0, 1]])
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    rays = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], axis=-1)
    times = np.linspace(0.0, scene.duration, frames)
    obj = np.asarray(scene.virtual_objects[0].position, np.float64)
    photo_pos = np.mean([k.position for k in scene.keyframes], axis=0) + np.asarray(photo_offset, np.float64)
    rig = Rig(scene, envmaps=False)
    try:
        light = rig.light_scale(scene.duration)
        pts, rad = [], []
        for t in times:
            pose = rig.rgbd_pose(float(t))
            radiance, z = rig.renderer.render_pinhole(pose, K, w, h, light)
            ok = (z > 0) & (z <= cam.depth_max_m) & np.isfinite(radiance).all(axis=-1)
            cam_pts = rays[ok] * z[ok][:, None]
            pts.append(cam_pts @ pose[:3, :3].T + pose[:3, 3])
            rad.append(radiance[ok].astype(np.float64))
        points, radiance = voxel_merge(np.concatenate(pts), np.concatenate(rad), voxel)
        truth = np.clip(radiance, 0.0, None).astype(np.float32)
        ldr = scanner_ldr(truth, exposure, scene.sensor_effects)
        target = np.mean([k.look_at for k in scene.keyframes], axis=0)
        over = overexposed(ldr)
        if aim is not None:
            target = aim
        elif photo_target == "overexposed" and over.any():
            target = points[over].mean(axis=0)
        photo_K, photo_pose = camera_looking_at(photo_pos, target, photo_fov_deg, photo_size)
        photo, _ = rig.renderer.render_pinhole(photo_pose, photo_K, int(photo_size[0]), int(photo_size[1]), light)
    finally:
        rig.release()
    photo = (np.clip(photo, 0.0, None) * np.float32(photo_exposure)).astype(np.float32)
    return SyntheticCase(points.astype(np.float32), truth, ldr, photo, obj, float(exposure), float(photo_exposure),
                         photo_pos, scene.name, photo_K, photo_pose)
