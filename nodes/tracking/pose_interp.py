"""Pose interpolation node: the fisheye pose at each fisheye frame's stamp from the RGB-D poses (paper §4.3).

The cameras are not synchronised. For each fisheye frame the RGB-D pose at its stamp is
interpolated between the bracketing RGB-D poses or, when the frame is newer than the last pose
(the live case, "the two most recent RGB-D poses"), extrapolated from the last two at most
``max_extrapolation_s`` ahead; then ``world_from_fisheye = world_from_rgbd(t) @ inv(fisheye_from_rgbd)``.
A frame that can be neither waits in a small hold queue for a newer pose; it is dropped when a
fisheye frame more than ``max_hold_s`` newer has arrived (``hold_expired``), when more than
``hold_frames`` wait (``hold_overflow``), or at the end (``unresolved_at_close``) - each with a last
try at extrapolation. With ``wait_for_bracket`` every frame newer than the last pose waits for the
next pose (exact interpolation, up to one RGB-D period of latency).

Extrinsics (``fisheye_from_rgbd``), from exactly one place: the ``extrinsics`` param (a file written by
``probeless calibrate extrinsics``, or a scene file), the ``translation`` + ``rpy_deg`` params, or the
``fisheye_from_rgbd`` input (e.g. the synthetic rig's or a recording's ``rig/fisheye_from_rgbd``). Frames wait
(in the hold queue) until the input has arrived when no param gives them. When a param gives them and the input
disagrees by more than ``max_mismatch_m`` / ``max_mismatch_deg``, the node fails naming both: a calibration that
does not match the rig is an error, never silently one or the other.

Outputs, only for frames that got a pose: ``fisheye_pose`` (stamped exactly like the frame, frame
id = the poses' frame, child = the image's frame id) then ``fisheye`` (the frame, unchanged).
Counters for every outcome (published by reason, dropped by reason, pose insert outcomes) are in
``self.counts`` and logged at close.
"""

from __future__ import annotations

import bisect
from collections import Counter, deque
from dataclasses import dataclass

import numpy as np

from probeless.errors import ParamError
from probeless.geom.rotation import invert_transform, transform_from_rpy
from probeless.messages.geometry import PoseStamped
from probeless.messages.header import Header
from probeless.messages.sensor import Image
from probeless.runtime import Node, param
from probeless.runtime.params import file_load_problem
from probeless.tracking.interp import PoseBuffer


def fisheye_from_rgbd(translation, rpy_deg) -> np.ndarray:
    """4x4 fisheye_from_rgbd from the scene-file convention: p_fisheye = R p_rgbd + t, R from roll/pitch/yaw."""
    return transform_from_rpy(translation, rpy_deg)


def _extrinsics_problem(path: str) -> str | None:
    from probeless.cameras.extrinsics import load_extrinsics

    return file_load_problem(path, load_extrinsics)


def _rpy_problem(rpy, params) -> str | None:
    given = [params.extrinsics != "", params.translation is not None or rpy is not None]
    if (params.translation is None) != (rpy is None):
        return "give translation and rpy_deg together (or neither)"
    if all(given):
        return "give the extrinsics file or translation + rpy_deg, not both"
    return None


def param_extrinsics(p) -> np.ndarray | None:
    """fisheye_from_rgbd (4, 4) from the params, or None when they leave it to the input."""
    if p.extrinsics:
        from probeless.cameras.extrinsics import load_extrinsics

        return load_extrinsics(p.extrinsics)
    if p.translation is not None:
        return fisheye_from_rgbd(p.translation, p.rpy_deg)
    return None


def _ns(seconds: float) -> int:
    return int(round(seconds * 1e9))


class PoseInterp(Node):
    """RGB-D ``pose`` + ``fisheye`` frames -> ``fisheye_pose`` + ``fisheye`` pairs with identical stamps."""

    INPUTS = {"pose": PoseStamped, "fisheye": Image, "fisheye_from_rgbd": PoseStamped}
    OUTPUTS = {"fisheye_pose": PoseStamped, "fisheye": Image}

    @dataclass(frozen=True)
    class Params:
        extrinsics: str = param("", path="file", must_exist=True, check=_extrinsics_problem,
                                doc="fisheye_from_rgbd from a `probeless calibrate extrinsics` output (or a scene "
                                    "file); '' = the translation/rpy_deg params or the fisheye_from_rgbd input")
        translation: tuple[float, ...] | None = param(None, length=3, finite=True,
                                                      doc="fisheye_from_rgbd translation t (p_fisheye = R p_rgbd + t) "
                                                          "[m]; null = from `extrinsics` or the input")
        rpy_deg: tuple[float, ...] | None = param(None, length=3, finite=True, check=_rpy_problem,
                                                  doc="fisheye_from_rgbd rotation R = Rz(yaw) Ry(pitch) Rx(roll) "
                                                      "[deg]; with translation")
        max_mismatch_m: float = param(0.001, min=0.0, max=10.0, doc="largest translation difference between a "
                                                                    "param's extrinsics and the input's [m]")
        max_mismatch_deg: float = param(0.1, min=0.0, max=180.0, doc="largest rotation difference between a "
                                                                     "param's extrinsics and the input's [deg]")
        max_extrapolation_s: float = param(0.05, min=0.0, max=10.0, doc="how far beyond the newest (or oldest) "
                                                                        "pose a pose may be extrapolated [s]")
        wait_for_bracket: bool = param(False, doc="hold frames newer than the last pose until the next pose "
                                                  "arrives (interpolate, do not extrapolate)")
        max_hold_s: float = param(0.2, min=0.0, max=60.0, doc="drop a held frame once a fisheye frame this much "
                                                              "newer has arrived [s, stamp time]")
        hold_frames: int = param(8, min=0, max=10000, doc="most frames waiting for a newer pose; 0 = never wait")
        buffer_length: int = param(64, min=2, max=100000, doc="RGB-D poses kept [count]")
        max_gap_s: float = param(0.25, min=0.0, max=60.0, doc="never use two poses further apart (lost tracking) [s]")
        jump_back_s: float = param(1.0, min=0.0, max=3600.0, doc="a stamp this much older than the newest is a "
                                                                 "time jump (replay loop): forget the past [s]")

    def setup(self) -> None:
        p = self.params
        self.fixed = param_extrinsics(p)
        self.rgbd_from_fisheye = None if self.fixed is None else invert_transform(self.fixed)
        self.input_extrinsics: np.ndarray | None = None  # the last fisheye_from_rgbd input taken
        self.poses = PoseBuffer(p.buffer_length, _ns(p.jump_back_s), _ns(p.max_gap_s))
        self.max_extrap_ns, self.max_hold_ns, self.jump_ns = (_ns(p.max_extrapolation_s), _ns(p.max_hold_s),
                                                              _ns(p.jump_back_s))
        self.held: list[Image] = []                    # sorted by stamp
        self.recent: deque[int] = deque(maxlen=p.hold_frames + 64)  # fisheye stamps seen, for duplicates
        self.newest_fisheye: int | None = None
        self.world_frame = "world"
        self.counts: Counter[str] = Counter()

    def on_input(self, name: str, msg) -> None:
        if name == "pose":
            self._on_pose(msg)
        elif name == "fisheye":
            self._on_fisheye(msg)
        else:
            self._on_extrinsics(msg)

    def _on_extrinsics(self, msg: PoseStamped) -> None:
        T = msg.target_from_source
        if self.fixed is not None:
            dt = float(np.linalg.norm(T[:3, 3] - self.fixed[:3, 3]))
            cos = (np.trace(T[:3, :3].T @ self.fixed[:3, :3]) - 1.0) / 2.0
            deg = float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))
            if dt > self.params.max_mismatch_m or deg > self.params.max_mismatch_deg:
                key = "extrinsics" if self.params.extrinsics else "translation"
                raise ParamError(f"the fisheye_from_rgbd input differs from the param's by {dt * 1000:.1f} mm and "
                                 f"{deg:.2f} deg (limits {self.params.max_mismatch_m * 1000:.1f} mm, "
                                 f"{self.params.max_mismatch_deg} deg): the calibration does not match the rig",
                                 node_id=self.ctx.node_id, key=key)
            self.counts["extrinsics_input_agrees"] += 1
            return
        if self.input_extrinsics is not None and np.array_equal(T, self.input_extrinsics):
            return  # a repeat (sources republish it for restarted nodes)
        self.input_extrinsics = T
        self.rgbd_from_fisheye = invert_transform(T)
        self.counts["extrinsics_updates"] += 1
        self.ctx.log.info("fisheye_from_rgbd from the input (stamp %d): translation %s", msg.header.stamp_ns,
                          np.round(T[:3, 3], 4).tolist())
        self._release()

    def _on_pose(self, msg: PoseStamped) -> None:
        t = msg.header.stamp_ns
        outcome = self.poses.insert(t, msg.target_from_source)
        self.counts[f"pose:{outcome}"] += 1
        self.world_frame = msg.header.frame_id or "world"
        if outcome == "time_jump":  # frames held from the previous pass can never get a pose now
            self._drop_held(lambda s: s - t > self.jump_ns, "time_jump")
        self._release()

    def _on_fisheye(self, img: Image) -> None:
        t = img.header.stamp_ns
        if self.newest_fisheye is not None and self.newest_fisheye - t > self.jump_ns:
            self._drop_held(lambda s: s - t > self.jump_ns, "time_jump")
            self.recent.clear()
            self.newest_fisheye = None
        if t in self.recent:
            self.counts["drop:duplicate_stamp"] += 1
            return
        self.recent.append(t)
        self.newest_fisheye = t if self.newest_fisheye is None else max(self.newest_fisheye, t)
        bisect.insort(self.held, img, key=lambda m: m.header.stamp_ns)
        self._release()

    def _release(self) -> None:
        """Publish or drop every held frame that can be decided now; cap the queue."""
        kept = []
        for img in self.held:
            expired = self.newest_fisheye - img.header.stamp_ns > self.max_hold_ns
            if not self._resolve(img, "hold_expired" if expired else None):
                kept.append(img)
        while len(kept) > self.params.hold_frames:
            self._resolve(kept.pop(0), "hold_overflow")
        self.held = kept

    def _waiting(self, t: int) -> bool:
        """True while a newer pose may still bracket stamp ``t`` (or the poses are from before a time jump)."""
        newest = self.poses.newest_ns
        return newest is None or t > newest or newest - t > self.jump_ns

    def _resolve(self, img: Image, final: str | None) -> bool:
        """Publish ``img`` with its pose or drop it (True), or keep holding it (False).

        ``final`` names why this is the frame's last chance; then it is extrapolated if it can be.
        """
        t = img.header.stamp_ns
        if self.rgbd_from_fisheye is None:  # no extrinsics yet: wait for the input
            if final:
                self.counts["drop:no_extrinsics"] += 1
            return bool(final)
        waiting = self._waiting(t)
        extrap = self.max_extrap_ns if final or not (self.params.wait_for_bracket and waiting) else 0
        with self.ctx.timed("interpolate"):
            T, reason = self.poses.query(t, extrap)
        if T is not None:
            pose = PoseStamped(Header(t, self.world_frame), img.header.frame_id or "fisheye",
                               T @ self.rgbd_from_fisheye)
            self.ctx.publish("fisheye_pose", pose)
            self.ctx.publish("fisheye", img)
            self.counts[f"published:{reason}"] += 1
            return True
        if waiting and final is None:
            return False
        self.counts[f"drop:{final if waiting else reason}"] += 1
        return True

    def _drop_held(self, stale, reason: str) -> None:
        keep = [m for m in self.held if not stale(m.header.stamp_ns)]
        if len(keep) < len(self.held):
            self.counts[f"drop:{reason}"] += len(self.held) - len(keep)
        self.held = keep

    def close(self) -> None:
        for img in getattr(self, "held", []):
            self._resolve(img, "unresolved_at_close")
        if not hasattr(self, "counts"):
            return
        self.held = []
        published = sum(n for k, n in self.counts.items() if k.startswith("published:"))
        dropped = {k[5:]: n for k, n in self.counts.items() if k.startswith("drop:")}
        self.ctx.log.info("%d fisheye pose(s) published; counts: %s", published, dict(sorted(self.counts.items())))
        if dropped:
            self.ctx.log.warning("dropped %d fisheye frame(s): %s", sum(dropped.values()), dropped)
