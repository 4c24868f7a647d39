"""RGB-D / fisheye frame pairs and camera infos from an MCAP recording of the rig (for extrinsics).

Topics are ``<node_id>/<output>``; the rig's outputs are ``rgb``, ``depth``, ``fisheye``,
``rgbd/camera_info`` and ``fisheye/camera_info``. Frames are paired by header stamp: each fisheye
frame with the RGB frame nearest in time, and the depth frame nearest to that. Pooling matches
over pairs is only right if the rig did not move between the two stamps (hence ``max_dt``) or if
that motion is compensated: :func:`pair_matches` carries the RGB-D points to the fisheye stamp
with the motion estimated against the neighbouring RGB frame (:mod:`probeless.cameras.motion`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from probeless.bag.reader import BagReader
from probeless.bag.writer import recording_paths
from probeless.errors import CalibrationError
from probeless.messages.sensor import CameraInfo, DepthImage, Image


@dataclass(frozen=True)
class RigTopics:
    """The recorded topics the extrinsics calibration reads."""

    rgb: str
    depth: str
    fisheye: str
    rgbd_info: str
    fisheye_info: str

    @classmethod
    def of_node(cls, node_id: str = "rig") -> RigTopics:
        """The topics of a rig node called ``node_id``."""
        return cls(f"{node_id}/rgb", f"{node_id}/depth", f"{node_id}/fisheye", f"{node_id}/rgbd/camera_info",
                   f"{node_id}/fisheye/camera_info")


@dataclass(frozen=True)
class FramePair:
    """One fisheye image and the RGB-D frame nearest to it in time."""

    rgb: np.ndarray         # (H, W, 3) uint8 RGB, or (H, W) uint8 grey
    depth_m: np.ndarray     # (H, W) float32 metres, 0 = invalid
    fisheye: np.ndarray     # (H', W', 3) uint8 RGB, or grey
    rgb_stamp_ns: int
    fisheye_stamp_ns: int
    neighbour_rgb: np.ndarray | None = None  # the RGB frame on the other side of the fisheye stamp
    neighbour_stamp_ns: int | None = None

    @property
    def dt_s(self) -> float:
        """fisheye stamp - RGB stamp [s]."""
        return (self.fisheye_stamp_ns - self.rgb_stamp_ns) * 1e-9


def nearest(stamps: np.ndarray, t: int) -> int:
    """Index of the stamp nearest to ``t`` in the sorted, non-empty ``stamps``."""
    k = int(np.searchsorted(stamps, t))
    cands = [j for j in (k - 1, k) if 0 <= j < len(stamps)]
    return min(cands, key=lambda j: abs(int(stamps[j]) - t))


def pair_stamps(fisheye: Sequence[int], rgb: Sequence[int], depth: Sequence[int], max_dt_ns: int,
                count: int) -> list[tuple[int, int, int]]:
    """Up to ``count`` (fisheye, rgb, depth) stamp triples with |fisheye - rgb| and |depth - rgb| at
    most ``max_dt_ns``, spread evenly over the candidates in time."""
    rgb_s, depth_s = np.sort(np.asarray(rgb, np.int64)), np.sort(np.asarray(depth, np.int64))
    if len(rgb_s) == 0 or len(depth_s) == 0:
        return []
    out = []
    for f in sorted(int(s) for s in fisheye):
        r = int(rgb_s[nearest(rgb_s, f)])
        d = int(depth_s[nearest(depth_s, r)])
        if abs(f - r) <= max_dt_ns and abs(d - r) <= max_dt_ns:
            out.append((f, r, d))
    if len(out) > count:
        out = [out[k] for k in sorted(set(np.linspace(0, len(out) - 1, count).round().astype(int)))]
    return out


def neighbour_stamp(rgb: Sequence[int], rgb_stamp: int, fisheye_stamp: int, max_gap_ns: int) -> int | None:
    """The RGB stamp next to ``rgb_stamp`` on the side of ``fisheye_stamp`` (the frames bracketing
    the fisheye frame), None if there is none within ``max_gap_ns`` of ``rgb_stamp``."""
    s = np.sort(np.asarray(rgb, np.int64))
    k = int(np.searchsorted(s, rgb_stamp))
    j = k + 1 if fisheye_stamp >= rgb_stamp else k - 1
    if not (0 <= k < len(s) and s[k] == rgb_stamp and 0 <= j < len(s)) or abs(int(s[j]) - rgb_stamp) > max_gap_ns:
        return None
    return int(s[j])


def image_array(msg: Image, where: str) -> np.ndarray:
    """uint8 RGB (H, W, 3) or grey (H, W) pixels of an Image message."""
    enc = msg.encoding
    conv = {"rgb8": None, "mono8": None, "bgr8": cv2.COLOR_BGR2RGB, "rgba8": cv2.COLOR_RGBA2RGB,
            "bgra8": cv2.COLOR_BGRA2RGB}
    if enc not in conv:
        raise CalibrationError(f"{where}: image encoding {enc!r} is not supported (need 8-bit rgb/bgr/mono)")
    data = msg.data[..., 0] if enc == "mono8" else msg.data
    return np.ascontiguousarray(data if conv[enc] is None else cv2.cvtColor(data, conv[enc]))


class RigRecording:
    """Read camera infos and frame pairs from a recording (one file or a split set)."""

    def __init__(self, path: str | Path, topics: RigTopics):
        self.paths = recording_paths(path)
        self.topics = topics

    def _messages(self, topics: Sequence[str]):
        for p in self.paths:
            with BagReader(p) as reader:
                for m in reader.messages(topics):
                    yield m.topic, reader.decode(m)

    def camera_info(self, topic: str) -> CameraInfo:
        """The first CameraInfo on ``topic``; CalibrationError if there is none."""
        for _, msg in self._messages([topic]):
            if isinstance(msg, CameraInfo):
                return msg
        raise CalibrationError(f"{self.paths[0]}: no CameraInfo on topic {topic!r}")

    def pairs(self, max_dt_s: float, count: int, neighbours_within_s: float | None = None) -> list[FramePair]:
        """Up to ``count`` frame pairs (see :func:`pair_stamps`); CalibrationError naming the topics if none.

        With ``neighbours_within_s``, each pair also holds the RGB frame on the other side of the
        fisheye stamp (see :func:`neighbour_stamp`), for motion compensation.
        """
        t = self.topics
        stamps: dict[str, list[int]] = {t.rgb: [], t.depth: [], t.fisheye: []}
        for topic, msg in self._messages(list(stamps)):
            stamps[topic].append(msg.header.stamp_ns)
        for topic, s in stamps.items():
            if not s:
                raise CalibrationError(f"{self.paths[0]}: no messages on topic {topic!r}")
        triples = pair_stamps(stamps[t.fisheye], stamps[t.rgb], stamps[t.depth], int(max_dt_s * 1e9), count)
        if not triples:
            raise CalibrationError(f"{self.paths[0]}: no fisheye frame on {t.fisheye!r} has an RGB-D frame "
                                   f"within --max-dt {max_dt_s} s")
        nbs = [None if neighbours_within_s is None else
               neighbour_stamp(stamps[t.rgb], r, f, int(neighbours_within_s * 1e9)) for f, r, _ in triples]
        want = {t.fisheye: {f for f, _, _ in triples}, t.rgb: {r for _, r, _ in triples} | set(nbs) - {None},
                t.depth: {d for _, _, d in triples}}
        got: dict[tuple[str, int], np.ndarray] = {}
        for topic, msg in self._messages(list(want)):
            stamp = msg.header.stamp_ns
            if stamp in want[topic] and (topic, stamp) not in got:
                got[(topic, stamp)] = self._pixels(topic, msg)
        return [FramePair(got[(t.rgb, r)], got[(t.depth, d)], got[(t.fisheye, f)], r, f,
                          None if nb is None else got[(t.rgb, nb)], nb) for (f, r, d), nb in zip(triples, nbs)]

    def _pixels(self, topic: str, msg) -> np.ndarray:
        want = DepthImage if topic == self.topics.depth else Image
        if not isinstance(msg, want):
            raise CalibrationError(f"{self.paths[0]}: topic {topic!r} holds {type(msg).__name__}, "
                                   f"expected {want.__name__}")
        return msg.metres() if want is DepthImage else image_array(msg, f"{self.paths[0]}: topic {topic!r}")


@dataclass(frozen=True)
class PairMatches:
    """The matches of one frame pair, with the RGB-D points moved to the fisheye's stamp."""

    points_rgbd: np.ndarray      # (N, 3) in the RGB-D frame at the fisheye stamp (if compensated) [m]
    pixels_fisheye: np.ndarray   # (N, 2)
    candidates: int              # matches before RANSAC
    motion: np.ndarray | None    # rgbd(fisheye stamp) from rgbd(rgb stamp), None when not compensated


def pair_matches(pair: FramePair, rgbd_K: np.ndarray, fisheye, init: np.ndarray | None = None,
                 compensate: bool = True) -> PairMatches:
    """Matches of one pair (:func:`~probeless.cameras.matching.match_rgbd_fisheye`); with
    ``compensate``, the points are carried to the fisheye stamp by the RGB-D motion estimated
    against the neighbour frame (CalibrationError if the pair has none or it cannot be estimated)."""
    from probeless.cameras.matching import match_rgbd_fisheye
    from probeless.cameras.motion import motion_to_stamp, rgbd_motion

    m = match_rgbd_fisheye(pair.rgb, pair.depth_m, rgbd_K, pair.fisheye, fisheye, init)
    if not compensate:
        return PairMatches(m.points_rgbd, m.pixels_fisheye, m.candidates, None)
    if pair.neighbour_rgb is None:
        raise CalibrationError(f"RGB frame {pair.rgb_stamp_ns} has no neighbour frame on the other side of "
                               f"fisheye frame {pair.fisheye_stamp_ns} to estimate the rig's motion")
    b_from_a, _ = rgbd_motion(pair.rgb, pair.depth_m, pair.neighbour_rgb, rgbd_K)
    T = motion_to_stamp(b_from_a, pair.rgb_stamp_ns, pair.neighbour_stamp_ns, pair.fisheye_stamp_ns)
    return PairMatches(m.points_rgbd @ T[:3, :3].T + T[:3, 3], m.pixels_fisheye, m.candidates, T)
