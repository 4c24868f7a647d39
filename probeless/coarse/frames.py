"""Fisheye frames with poses for offline coarse-model runs: a synthetic scene or a rig recording.

Frames come in the texturer's runtime model (ideal omnidir, D = 0): a scene's Kannala-Brandt
fisheye, or a recording's raw model, is undistorted through a look-up table first, as the
``fisheye_undistort`` node does in a graph. Poses are the rig's true fisheye poses
(``gt/fisheye_pose``), so an offline run measures the coarse model alone.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from probeless.cameras import model_from_info
from probeless.cameras.omnidir import OmnidirModel
from probeless.cameras.undistort import build_lut, remap
from probeless.errors import BagError, ProbelessError

FOV_MARGIN_DEG = 2.0


@dataclass(frozen=True)
class FisheyeFrame:
    """One fisheye frame ready for the texturer."""

    stamp_ns: int                   # capture time [ns]
    t_s: float                      # time since the first frame [s]
    image: np.ndarray               # (H, W, 3) uint8 RGB in the runtime model
    world_from_fisheye: np.ndarray  # (4, 4) true pose
    light_scale: np.ndarray | None = None  # the scene's light on/off scales at this time (scenes only)


@dataclass
class FrameSource:
    """Where frames come from, their runtime model and the room."""

    name: str
    model: OmnidirModel
    floorplan: np.ndarray
    ceiling_height: float
    frames: Iterator[FisheyeFrame]
    count: int
    fov_deg: float = 180.0          # the camera's field of view (its image circle) [deg]
    rig: object | None = None       # probeless.scene.rig.Rig for scenes (renderer, exposure): ground truth
    extra: dict = field(default_factory=dict)

    @property
    def texture_fov_deg(self) -> float:
        """Field of view the texturer uses: 2 degrees inside the image circle, whose rim is blended with black."""
        return self.fov_deg - FOV_MARGIN_DEG


def runtime_model(model, fov_deg: float) -> tuple[OmnidirModel, tuple | None]:
    """(runtime omnidir model, LUT to undistort into it, None when ``model`` already is one)."""
    if isinstance(model, OmnidirModel) and not np.any(np.asarray(model.D)):
        return model, None
    target = OmnidirModel.from_fov(model.width, model.height, min(fov_deg, 185.0))
    return target, build_lut(model, target)


def scene_source(path: str | Path, duration: float | None = None, *, cube_size: int = 512,
                 stride: int = 1) -> FrameSource:
    """Every ``stride``-th fisheye frame of a scene file rendered by the synthetic rig in [0, duration]."""
    from probeless.scene.parse import load_scene
    from probeless.scene.rig import Rig, frame_schedule

    scene = load_scene(path)
    rig = Rig(scene, envmaps=False, fisheye_cube_size=cube_size)
    model, lut = runtime_model(rig.fisheye, scene.fisheye.fov_deg)
    events = [e for e in frame_schedule(scene, duration) if e.kind == "fisheye"][::max(1, stride)]

    def gen() -> Iterator[FisheyeFrame]:
        for e in events:
            image, pose = rig.render_fisheye(e)
            yield FisheyeFrame(e.stamp_ns, e.t - events[0].t, image if lut is None else remap(image, lut), pose,
                               rig.light_scale(e.t))

    return FrameSource(scene.name, model, scene.floorplan, scene.ceiling_height, gen(), len(events),
                       scene.fisheye.fov_deg, rig)


def _one(topics: dict, suffix: str, path) -> str:
    found = sorted(t for t in topics if t.endswith(suffix))
    if len(found) != 1:
        raise BagError(f"{path}: need exactly one <id>{suffix} topic, found {found or 'none'}")
    return found[0]


def bag_source(path: str | Path, fov_deg: float = 180.0) -> FrameSource:
    """Fisheye frames, camera info, true fisheye poses and floorplan of a rig recording (``scene render``)."""
    from probeless.bag.reader import BagReader

    with BagReader(path) as reader:
        topics = reader.topics()
        t_img, t_info = _one(topics, "/fisheye", path), _one(topics, "/fisheye/camera_info", path)
        t_pose, t_plan = _one(topics, "/gt/fisheye_pose", path), _one(topics, "/floorplan", path)
        info = reader.decode(next(iter(reader.messages(t_info))))
        plan = reader.decode(next(iter(reader.messages(t_plan))))
        poses = {m.header.stamp_ns: m.target_from_source for m in map(reader.decode, reader.messages(t_pose))}
    try:
        model, lut = runtime_model(model_from_info(info), fov_deg)
    except ProbelessError as exc:
        raise BagError(f"{path}: {t_info}: {exc}") from exc

    def gen() -> Iterator[FisheyeFrame]:
        t0 = None
        with BagReader(path) as reader:
            for m in reader.messages(t_img):
                img = reader.decode(m)
                stamp = img.header.stamp_ns
                if stamp not in poses:
                    continue  # a frame without its pose cannot be placed
                t0 = stamp if t0 is None else t0
                data = img.data if lut is None else remap(img.data, lut)
                yield FisheyeFrame(stamp, (stamp - t0) * 1e-9, data, poses[stamp])

    count = min(topics[t_img].count, len(poses))
    return FrameSource(Path(path).stem, model, plan.vertices, plan.ceiling_height, gen(), count, fov_deg)


def open_source(path: str | Path, duration: float | None = None) -> FrameSource:
    """A scene file (.yaml) or a recording (.mcap)."""
    p = Path(path)
    if p.suffix in (".yaml", ".yml"):
        return scene_source(p, duration)
    if p.suffix == ".mcap" or p.is_dir():
        return bag_source(p)
    raise ProbelessError(f"{path}: expected a scene file (.yaml) or a recording (.mcap)")
