"""Pose interpolation in time: constant-velocity inter/extrapolation and a bounded pose buffer.

The RGB-D and fisheye cameras are not synchronised, so the fisheye pose at a fisheye stamp comes
from the RGB-D poses around it (paper §4.3: translation linearly, rotation by quaternion slerp).
``interpolate_pose`` also extrapolates (t outside [t0, t1]): the same formulas continued, i.e.
constant linear velocity of the camera origin and constant angular velocity.

Quaternions are ``[x, y, z, w]`` (scipy order); slerp and the rest are in :mod:`probeless.geom.rotation`.
"""

from __future__ import annotations

import bisect

import numpy as np

from probeless.errors import ProbelessError
from probeless.geom.rotation import matrix_from_quat, quat_from_matrix, slerp, transform_from


def interpolate_pose(T0: np.ndarray, t0: float, T1: np.ndarray, t1: float, t: float) -> np.ndarray:
    """Pose at time ``t`` from poses T0 at t0 and T1 at t1 (4x4 target_from_source, any time unit).

    Translation is linear in time and rotation slerps (shortest arc); t outside [t0, t1]
    extrapolates at the constant velocities the two poses imply.
    """
    if t1 == t0:
        raise ProbelessError(f"interpolate_pose: both poses have the stamp {t0}, no time base")
    s = (t - t0) / (t1 - t0)
    T0, T1 = np.asarray(T0, dtype=np.float64), np.asarray(T1, dtype=np.float64)
    q = slerp(quat_from_matrix(T0[:3, :3]), quat_from_matrix(T1[:3, :3]), s)
    return transform_from(matrix_from_quat(q), T0[:3, 3] + s * (T1[:3, 3] - T0[:3, 3]))


class PoseBuffer:
    """The last ``length`` poses sorted by stamp [ns], with explicit handling of disorder.

    :meth:`insert` returns (and counts in :attr:`counts`) what happened to a pose:
    ``appended``; ``out_of_order`` (older than the newest, put in its place); ``duplicate`` (a pose
    with that stamp is kept: the new one replaces it, a re-estimate wins); ``stale`` (older than
    everything in a full buffer: dropped); ``time_jump`` (older than the newest by more than
    ``jump_back_ns``, as when a replay loops: the buffer is cleared, then the pose appended).
    """

    def __init__(self, length: int = 64, jump_back_ns: int = 1_000_000_000, max_gap_ns: int = 250_000_000):
        if length < 2:
            raise ProbelessError(f"PoseBuffer: length must be >= 2 to interpolate, got {length}")
        self.length, self.jump_back_ns, self.max_gap_ns = length, jump_back_ns, max_gap_ns
        self.stamps: list[int] = []
        self.poses: list[np.ndarray] = []
        self.counts: dict[str, int] = {}

    def __len__(self) -> int:
        return len(self.stamps)

    @property
    def newest_ns(self) -> int | None:
        return self.stamps[-1] if self.stamps else None

    def clear(self) -> None:
        self.stamps.clear()
        self.poses.clear()

    def insert(self, stamp_ns: int, T: np.ndarray) -> str:
        """Add a pose; returns the outcome (see the class docstring)."""
        outcome = self._insert(int(stamp_ns), np.asarray(T, dtype=np.float64))
        self.counts[outcome] = self.counts.get(outcome, 0) + 1
        return outcome

    def _insert(self, stamp: int, T: np.ndarray) -> str:
        if not self.stamps or stamp > self.stamps[-1]:
            outcome = "appended"
        elif self.stamps[-1] - stamp > self.jump_back_ns:
            self.clear()
            outcome = "time_jump"
        else:
            i = bisect.bisect_left(self.stamps, stamp)
            if i < len(self.stamps) and self.stamps[i] == stamp:
                self.poses[i] = T
                return "duplicate"
            if i == 0 and len(self.stamps) >= self.length:
                return "stale"
            self.stamps.insert(i, stamp)
            self.poses.insert(i, T)
            self._trim()
            return "out_of_order"
        self.stamps.append(stamp)
        self.poses.append(T)
        self._trim()
        return outcome

    def _trim(self) -> None:
        del self.stamps[:-self.length], self.poses[:-self.length]

    def query(self, t_ns: int, max_extrapolation_ns: int) -> tuple[np.ndarray | None, str]:
        """(pose at ``t_ns`` or None, reason).

        Reasons with a pose: ``exact`` (a pose has that stamp), ``interpolated`` (between the two
        bracketing poses), ``extrapolated`` (from the two newest, or two oldest, poses, at most
        ``max_extrapolation_ns`` beyond them). Without: ``empty``, ``single_pose`` (no velocity
        yet), ``beyond_extrapolation`` (newer than the newest pose by more), ``before_first``
        (older than the oldest pose by more), ``gap`` (the two poses it needs are more than
        ``max_gap_ns`` apart: tracking was lost in between).
        """
        t, st = int(t_ns), self.stamps
        if not st:
            return None, "empty"
        i = bisect.bisect_left(st, t)
        if i < len(st) and st[i] == t:
            return self.poses[i], "exact"
        if 0 < i < len(st):
            a, b, reason = i - 1, i, "interpolated"
        else:
            if len(st) < 2:
                return None, "single_pose"
            if i == 0 and st[0] - t > max_extrapolation_ns:
                return None, "before_first"
            if i == len(st) and t - st[-1] > max_extrapolation_ns:
                return None, "beyond_extrapolation"
            a, b, reason = (0, 1, "extrapolated") if i == 0 else (len(st) - 2, len(st) - 1, "extrapolated")
        if st[b] - st[a] > self.max_gap_ns:
            return None, "gap"
        return interpolate_pose(self.poses[a], st[a], self.poses[b], st[b], t), reason
