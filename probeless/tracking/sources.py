"""RGB-D frame sources for offline SLAM runs: dataset folders, scene files and recordings.

:func:`rgbd_samples` turns any of them into :class:`RgbdSample` s (colour, uint16 depth, pinhole K
and, where known, the ground-truth ``world_from_rgbd``):

* a dataset folder (TUM, Redwood/Open3D, 7-Scenes; :func:`probeless.datasets.detect.open_rgbd`),
  ground truth = the dataset's pose of the frame;
* a scene file (``*.yaml``): the synthetic rig renders its RGB-D frames (no envmaps), ground truth
  = the rig pose; it also describes its depth (range ``depth_max_m``, constant noise
  ``depth_noise_m``), which ``probeless eval slam`` uses unless told otherwise (:func:`.slam.source_params`);
* a recording (``*.mcap``) holding ``<id>/rgb``, ``<id>/depth``, ``<id>/rgbd/camera_info`` and
  optionally ``<id>/gt/rgbd_pose`` for one node id ``<id>``; colour and depth are paired by
  identical stamps.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import numpy as np

from probeless.errors import DatasetError


@dataclass(frozen=True)
class RgbdSample:
    """One registered colour/depth pair with its intrinsics and optional ground-truth pose."""

    stamp_ns: int                               # colour capture time [ns]
    rgb: np.ndarray                             # (H, W, 3) uint8 RGB
    depth: np.ndarray                           # (H, W) uint16, 0 = invalid [depth units]
    depth_scale: float                          # depth units per metre
    K: np.ndarray                               # (3, 3) pinhole camera matrix [px]
    gt_world_from_rgbd: np.ndarray | None = None  # (4, 4) ground truth, None where unknown
    depth_range_m: float | None = None          # where the source knows its sensor is accurate: depth up to this [m]
    depth_sigma: tuple[float, float, float] | None = None  # its depth noise a + b (z - z0)^2 [m], where known


def _window(n: int, start: int, max_frames: int, stride: int) -> range:
    """Indices start, start + stride, ... of a sequence of ``n``, at most ``max_frames`` (0 = all)."""
    if start < 0 or max_frames < 0 or stride < 1:
        raise DatasetError(f"frame selection start={start}, max_frames={max_frames}, stride={stride}: "
                           "need start >= 0, max_frames >= 0, stride >= 1")
    r = range(start, n, stride)
    return r[:max_frames] if max_frames else r


def dataset_samples(path: Path, start: int, max_frames: int, stride: int) -> tuple[Iterator[RgbdSample], int]:
    """Samples of an RGB-D dataset folder (frames decoded lazily)."""
    from probeless.datasets.base import read_color, read_depth
    from probeless.datasets.detect import open_rgbd

    seq = open_rgbd(path)
    idx = _window(len(seq.frames), start, max_frames, stride)
    K = seq.intrinsics.K

    def gen() -> Iterator[RgbdSample]:
        for k in idx:
            f = seq.frames[k]
            yield RgbdSample(f.stamp_ns, read_color(f.rgb_path), read_depth(f.depth_path, seq.depth_invalid),
                             seq.depth_scale, K, f.pose)

    return gen(), len(idx)


def scene_samples(path: Path, start: int, max_frames: int, stride: int) -> tuple[Iterator[RgbdSample], int]:
    """Samples rendered by the synthetic rig from a scene file (the GL renderer lives while iterating)."""
    from probeless.scene.parse import load_scene
    from probeless.scene.rig import RGBD_FRAME, Rig, frame_schedule

    scene = load_scene(path)
    events = [e for e in frame_schedule(scene) if e.kind == RGBD_FRAME]
    idx = _window(len(events), start, max_frames, stride)

    def gen() -> Iterator[RgbdSample]:
        rig = Rig(scene, envmaps=False)
        try:
            for k in idx:
                rgb, depth, pose = rig.render_rgbd(events[k])
                # the rig's depth noise does not grow with distance: its whole range is as good as near depth
                yield RgbdSample(events[k].stamp_ns, rgb, depth, 1000.0, scene.rgbd.K, pose, scene.rgbd.depth_max_m,
                                 (scene.rgbd.depth_noise_m, 0.0, 0.0))
        finally:
            rig.release()

    return gen(), len(idx)


def _rig_topics(path: Path, topics: dict) -> str:
    """The node id prefix ``<id>`` of the recording's ``<id>/rgb`` + ``<id>/depth`` pair."""
    prefixes = sorted(t[:-len("/rgb")] for t in topics if t.endswith("/rgb") and t[:-len("/rgb")] + "/depth" in topics)
    if not prefixes:
        raise DatasetError(f"{path}: no <id>/rgb and <id>/depth topics (have: {', '.join(sorted(topics)) or 'none'})")
    if len(prefixes) > 1:
        raise DatasetError(f"{path}: several RGB-D sources {prefixes}; record one rig per file")
    if prefixes[0] + "/rgbd/camera_info" not in topics:
        raise DatasetError(f"{path}: {prefixes[0]}/rgbd/camera_info is missing (needed for the intrinsics)")
    return prefixes[0]


def bag_samples(path: Path, start: int, max_frames: int, stride: int) -> tuple[Iterator[RgbdSample], int]:
    """Samples of a recording; ``count`` assumes every colour image has its depth image."""
    from probeless.bag.reader import BagReader

    with BagReader(path) as reader:
        topics = reader.topics()
    pre = _rig_topics(path, topics)
    n = min(topics[pre + "/rgb"].count, topics[pre + "/depth"].count)
    idx = _window(n, start, max_frames, stride)
    wanted = set(idx)

    def gen() -> Iterator[RgbdSample]:
        last = idx[-1] if len(idx) else -1
        pending: dict[str, dict[int, object]] = {"rgb": {}, "depth": {}}
        K, k = None, 0
        with BagReader(path) as reader:
            gt = {}  # ground truth first (small), as it may be logged before or after its images
            for m in reader.messages(pre + "/gt/rgbd_pose"):
                pose = reader.decode(m)
                gt[pose.header.stamp_ns] = pose.target_from_source
            for m in reader.messages([pre + "/rgb", pre + "/depth", pre + "/rgbd/camera_info"]):
                if k > last:
                    return
                msg = reader.decode(m)
                kind = m.topic[len(pre) + 1:]
                if kind == "rgbd/camera_info":
                    K = msg.K
                    continue
                stamp = msg.header.stamp_ns
                pending[kind][stamp] = msg
                if stamp in pending["rgb"] and stamp in pending["depth"]:
                    rgb, depth = pending["rgb"].pop(stamp), pending["depth"].pop(stamp)
                    if k in wanted:
                        if K is None:
                            raise DatasetError(f"{path}: frame at {stamp} ns comes before any camera_info")
                        yield RgbdSample(stamp, rgb.data, depth.data, depth.depth_scale, K, gt.get(stamp))
                    k += 1

    return gen(), len(idx)


def rgbd_samples(path: str | Path, *, start: int = 0, max_frames: int = 0,
                 stride: int = 1) -> tuple[Iterator[RgbdSample], int]:
    """(samples, count) of a dataset folder, scene file or recording (see the module docstring)."""
    path = Path(path)
    if path.is_dir():
        return dataset_samples(path, start, max_frames, stride)
    if path.suffix in (".yaml", ".yml") and path.is_file():
        return scene_samples(path, start, max_frames, stride)
    if path.suffix == ".mcap" and path.is_file():
        return bag_samples(path, start, max_frames, stride)
    raise DatasetError(f"{path}: not an RGB-D dataset folder, scene file (.yaml) or recording (.mcap)")
