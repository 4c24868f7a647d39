"""Fisheye pose accuracy: the fisheye pose derived from RGB-D poses at each fisheye stamp vs the true one.

For every fisheye stamp t the RGB-D pose is taken in one of four ways, then composed with
``inv(fisheye_from_rgbd)`` and compared with the rig's true world_from_fisheye:

* ``interpolated``: between the two bracketing RGB-D poses (offline, or the node's wait_for_bracket);
* ``extrapolated``: from the two most recent RGB-D poses (stamps <= t): the live case of paper §4.3;
* ``nearest``: the RGB-D pose nearest in time, as is;
* ``latest``: the most recent RGB-D pose (stamp <= t), as is (no correction at all).

Errors: rotation angle of ``R_est^T R_true`` [deg] and distance between the origins [mm].
Sources: a scene file (poses from its trajectory, as :class:`probeless.scene.rig.Rig` computes them,
stamps from :func:`probeless.scene.rig.frame_schedule`; nothing is rendered) or a recording with
``<id>/gt/rgbd_pose`` and ``<id>/gt/fisheye_pose``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from probeless.errors import BagError
from probeless.geom.rotation import invert_transform, quat_from_matrix, transform_from
from probeless.tracking.interp import interpolate_pose

MODES = ("interpolated", "extrapolated", "nearest", "latest")


@dataclass(frozen=True)
class Track:
    """Poses (N, 4, 4) at strictly increasing stamps (N,) [ns]."""

    stamps_ns: np.ndarray
    poses: np.ndarray


@dataclass(frozen=True)
class Inputs:
    """What is evaluated: RGB-D poses, true fisheye poses at the fisheye stamps, the rig's extrinsics."""

    name: str
    rgbd: Track
    fisheye: Track
    fisheye_from_rgbd: np.ndarray


@dataclass(frozen=True)
class ModeErrors:
    """Per-frame errors of one mode; ``skipped`` counts fisheye stamps the mode had no pose for."""

    stamps_ns: np.ndarray
    rot_deg: np.ndarray
    trans_mm: np.ndarray
    skipped: int


def make_track(stamps_ns, poses, what: str) -> Track:
    """Track sorted by stamp; BagError naming ``what`` on repeated stamps."""
    stamps, poses = np.asarray(stamps_ns, dtype=np.int64), np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4)
    order = np.argsort(stamps, kind="stable")
    stamps, poses = stamps[order], poses[order]
    if np.any(np.diff(stamps) == 0):
        raise BagError(f"{what}: {int(np.sum(np.diff(stamps) == 0))} repeated stamp(s); one pose per stamp needed")
    return Track(stamps, poses)


def rgbd_pose_at(rgbd: Track, t: int, mode: str) -> np.ndarray | None:
    """world_from_rgbd at stamp ``t`` by ``mode`` (see the module docstring), None if it has none."""
    st, n = rgbd.stamps_ns, len(rgbd.stamps_ns)
    after = int(np.searchsorted(st, t, side="right"))  # poses[:after] have stamps <= t
    if after and st[after - 1] == t:
        return rgbd.poses[after - 1]
    if mode == "interpolated":
        ok = 0 < after < n
        return interpolate_pose(rgbd.poses[after - 1], st[after - 1], rgbd.poses[after], st[after], t) if ok else None
    if mode == "extrapolated":
        ok = after >= 2
        return (interpolate_pose(rgbd.poses[after - 2], st[after - 2], rgbd.poses[after - 1], st[after - 1], t)
                if ok else None)
    if mode == "latest":
        return rgbd.poses[after - 1] if after else None
    if mode == "nearest":
        return rgbd.poses[int(np.argmin(np.abs(st - t)))] if n else None
    raise ValueError(f"unknown mode {mode!r} (one of {MODES})")


def pose_errors(T_est: np.ndarray, T_true: np.ndarray) -> tuple[float, float]:
    """(rotation error [deg], translation error [mm]) of an estimated pose against the true one."""
    q = quat_from_matrix(T_est[:3, :3].T @ T_true[:3, :3])
    angle = 2.0 * np.arctan2(np.linalg.norm(q[:3]), q[3])  # accurate for tiny angles, unlike arccos
    return float(np.degrees(angle)), float(np.linalg.norm(T_est[:3, 3] - T_true[:3, 3]) * 1000.0)


def evaluate(inputs: Inputs, modes: tuple[str, ...] = MODES) -> dict[str, ModeErrors]:
    """Errors of every mode at every fisheye stamp."""
    rgbd_from_fisheye = invert_transform(inputs.fisheye_from_rgbd)
    out = {}
    for mode in modes:
        stamps, rot, trans = [], [], []
        for t, T_true in zip(inputs.fisheye.stamps_ns, inputs.fisheye.poses):
            T = rgbd_pose_at(inputs.rgbd, int(t), mode)
            if T is not None:
                r, d = pose_errors(T @ rgbd_from_fisheye, T_true)
                stamps.append(int(t)), rot.append(r), trans.append(d)
        out[mode] = ModeErrors(np.array(stamps, dtype=np.int64), np.array(rot), np.array(trans),
                               len(inputs.fisheye.stamps_ns) - len(stamps))
    return out


def _stats(x: np.ndarray) -> dict[str, float | None]:
    if not len(x):
        return {"median": None, "p95": None, "max": None}
    return {"median": float(np.median(x)), "p95": float(np.percentile(x, 95)), "max": float(np.max(x))}


def summarize(errors: dict[str, ModeErrors]) -> dict[str, dict]:
    """Per mode: frames evaluated, frames skipped, rotation [deg] and translation [mm] median/p95/max."""
    return {mode: {"n": len(e.rot_deg), "skipped": e.skipped, "rot_deg": _stats(e.rot_deg),
                   "trans_mm": _stats(e.trans_mm)} for mode, e in errors.items()}


def with_noise(track: Track, rot_deg: float, trans_mm: float, seed: int = 0) -> Track:
    """The track with independent Gaussian noise per pose: a rotation vector of sigma ``rot_deg`` per
    axis (applied in the camera frame) and a translation of sigma ``trans_mm`` per axis."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(seed)
    n = len(track.stamps_ns)
    dR = Rotation.from_rotvec(rng.normal(0.0, np.radians(rot_deg), (n, 3))).as_matrix()
    R = track.poses[:, :3, :3] @ dR
    t = track.poses[:, :3, 3] + rng.normal(0.0, trans_mm / 1000.0, (n, 3))
    return Track(track.stamps_ns, transform_from(R, t))


def scene_inputs(path: str | Path, duration: float | None = None) -> Inputs:
    """True RGB-D and fisheye poses of a scene file at its frame schedule's stamps (nothing rendered)."""
    from probeless.scene.parse import load_scene
    from probeless.scene.rig import FISHEYE_FRAME, RGBD_FRAME, frame_schedule
    from probeless.scene.trajectory import camera_pose

    scene = load_scene(path)
    events = frame_schedule(scene, duration)
    rgbd_from_fisheye = invert_transform(scene.fisheye_from_rgbd)

    def track(kind: str, camera_from_rgbd_pose) -> Track:  # the same formulas as Rig.rgbd_pose / fisheye_pose
        picked = [e for e in events if e.kind == kind]
        poses = [camera_from_rgbd_pose(camera_pose(scene.keyframes, e.t)) for e in picked]
        return make_track([e.stamp_ns for e in picked], poses, f"{path}: {kind} frames")

    return Inputs(scene.name, track(RGBD_FRAME, lambda T: T), track(FISHEYE_FRAME, lambda T: T @ rgbd_from_fisheye),
                  scene.fisheye_from_rgbd)


def scene_extrinsics(metadata: dict, where: str) -> np.ndarray:
    """fisheye_from_rgbd of the scene a recording was rendered from (its ``probeless.scene`` metadata)."""
    import yaml

    from probeless.geom.rotation import transform_from_rpy

    text = metadata.get("probeless.scene", {}).get("yaml")
    if text is None:
        raise BagError(f"{where}: no scene metadata (probeless.scene) to take fisheye_from_rgbd from; "
                       "give it with --fisheye-from-rgbd")
    try:
        e = yaml.safe_load(text)["rig"]["fisheye_from_rgbd"]
        return transform_from_rpy(e["translation"], e["rpy_deg"])
    except (KeyError, TypeError, yaml.YAMLError) as exc:
        raise BagError(f"{where}: scene metadata has no usable rig.fisheye_from_rgbd "
                       f"({type(exc).__name__}: {exc})") from None


def bag_inputs(path: str | Path, rig_id: str | None = None, pose_topic: str | None = None,
               fisheye_from_rgbd: np.ndarray | None = None) -> Inputs:
    """RGB-D poses (``<rig_id>/gt/rgbd_pose`` or ``pose_topic``, which must be in the same world frame) and
    true fisheye poses (``<rig_id>/gt/fisheye_pose``) of a recording; the rig id is found when there is one."""
    from probeless.bag.reader import BagReader
    from probeless.messages.geometry import PoseStamped

    suffix = "/gt/rgbd_pose"
    with BagReader(path) as reader:
        topics = reader.topics()
        if rig_id is None:
            ids = sorted(t[:-len(suffix)] for t in topics if t.endswith(suffix))
            if len(ids) != 1:
                raise BagError(f"{path}: {len(ids)} rig(s) with <id>{suffix} topics {ids}; name one with --rig-id")
            rig_id = ids[0]
        tracks = []
        for topic in (pose_topic or f"{rig_id}{suffix}", f"{rig_id}/gt/fisheye_pose"):
            if topic not in topics:
                raise BagError(f"{path}: no topic {topic!r} (topics: {', '.join(sorted(topics))})")
            msgs = [reader.decode(m) for m in reader.messages(topic)]
            if not msgs or not all(isinstance(m, PoseStamped) for m in msgs):
                raise BagError(f"{path}: topic {topic!r} holds no PoseStamped messages")
            tracks.append(make_track([m.header.stamp_ns for m in msgs], [m.target_from_source for m in msgs],
                                     f"{path}: {topic}"))
        if fisheye_from_rgbd is None:
            fisheye_from_rgbd = scene_extrinsics(reader.metadata(), str(path))
    return Inputs(f"{Path(path).name}:{rig_id}", tracks[0], tracks[1], np.asarray(fisheye_from_rgbd, dtype=np.float64))
