"""Trajectory metrics against independent references: Horn's quaternion method, scipy, known offsets/noise/drift."""

from __future__ import annotations

import numpy as np
import pytest
from references import horn_quaternion
from scipy.linalg import orthogonal_procrustes
from scipy.spatial.transform import Rotation

from probeless.tracking.metrics import align_umeyama, associate, ate, ate_errors, rpe, rpe_pairs


def pose(R: np.ndarray, t) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def random_trajectory(n: int, seed: int) -> list[np.ndarray]:
    """A smooth-ish random walk of world_from_camera poses."""
    rng = np.random.default_rng(seed)
    rots = Rotation.from_rotvec(np.cumsum(rng.normal(0, 0.02, (n, 3)), axis=0)).as_matrix()
    pos = np.cumsum(rng.normal(0, 0.01, (n, 3)), axis=0) + np.linspace(0, 1, n)[:, None] * [1.0, 0.3, -0.2]
    return [pose(R, p) for R, p in zip(rots, pos)]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_alignment_matches_horn_quaternion_and_scipy(seed):
    rng = np.random.default_rng(seed)
    est = rng.normal(0, 1, (50, 3))
    R_true = Rotation.random(random_state=seed).as_matrix()
    gt = est @ R_true.T + [0.3, -2.0, 1.1] + rng.normal(0, 0.05, (50, 3))
    R, t, s = align_umeyama(est, gt)
    R_horn, t_horn = horn_quaternion(est, gt)
    np.testing.assert_allclose(R, R_horn, atol=1e-9)
    np.testing.assert_allclose(t, t_horn, atol=1e-9)
    assert s == 1.0
    R_scipy, _ = Rotation.align_vectors(gt - gt.mean(0), est - est.mean(0))
    np.testing.assert_allclose(R, R_scipy.as_matrix(), atol=1e-9)
    R_proc, _ = orthogonal_procrustes(est - est.mean(0), gt - gt.mean(0))  # est_c @ R_proc ~ gt_c
    np.testing.assert_allclose(R, R_proc.T, atol=1e-9)


def test_alignment_never_returns_a_reflection():
    # Points that a reflection fits better than any rotation: a mirrored tetrahedron.
    est = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    gt = est * [1, 1, -1]
    R, _, _ = align_umeyama(est, gt)
    assert np.linalg.det(R) == pytest.approx(1.0)
    np.testing.assert_allclose(R, horn_quaternion(est, gt)[0], atol=1e-9)


def test_scale_is_recovered_with_scale():
    rng = np.random.default_rng(5)
    est = rng.normal(0, 1, (30, 3))
    R_true = Rotation.from_euler("xyz", [10, -40, 75], degrees=True).as_matrix()
    gt = 2.5 * est @ R_true.T + [1, 2, 3]
    R, t, s = align_umeyama(est, gt, with_scale=True)
    assert s == pytest.approx(2.5, rel=1e-12)
    np.testing.assert_allclose(R, R_true, atol=1e-12)
    np.testing.assert_allclose(t, [1, 2, 3], atol=1e-12)


def test_ate_is_zero_after_a_known_rigid_offset():
    gt = random_trajectory(200, seed=3)
    offset = pose(Rotation.from_euler("zyx", [35, -12, 80], degrees=True).as_matrix(), [4.0, -1.0, 0.5])
    est = [offset @ T for T in gt]  # the same trajectory expressed in another world frame
    result = ate(est, gt)
    assert result["n"] == 200
    assert result["rmse"] < 1e-12 and result["max"] < 1e-12


def test_ate_equals_the_rms_of_added_noise():
    gt = random_trajectory(3000, seed=4)
    rng = np.random.default_rng(9)
    noise = rng.normal(0, 0.01, (3000, 3))
    offset = pose(Rotation.from_euler("x", 70, degrees=True).as_matrix(), [1, 2, 3])
    est = []
    for T, e in zip(gt, noise):
        noisy = T.copy()
        noisy[:3, 3] += e
        est.append(offset @ noisy)
    result = ate(est, gt)
    noise_rms = np.sqrt(np.mean(np.sum(noise ** 2, axis=1)))
    assert result["rmse"] == pytest.approx(noise_rms, rel=0.01)
    errors = np.linalg.norm(noise, axis=1)
    assert result["median"] == pytest.approx(np.median(errors), rel=0.05)


def test_ate_counts_only_frames_with_estimate_and_ground_truth():
    gt = random_trajectory(20, seed=6)
    est = [T.copy() for T in gt]
    est[3][:3, 3] += [0.5, 0, 0]  # a bad estimate on a frame without ground truth must not count
    sparse_gt = [T if k in (0, 1, 2, 4, 10, 15) else None for k, T in enumerate(gt)]
    est[10] = None  # tracking failure
    out = ate_errors(est, sparse_gt)
    assert list(out["indices"]) == [0, 1, 2, 4, 15]
    assert ate(est, sparse_gt)["rmse"] < 1e-12


def tum_rpe(est, gt, pairs):
    """The RPE formula of TUM's evaluate_rpe.py: ominus(ominus(est_j, est_i), ominus(gt_j, gt_i)),
    ominus(a,b)=a^-1 b."""
    def ominus(a, b):
        return np.linalg.inv(a) @ b

    trans, rot = [], []
    for i, j in pairs:
        e = ominus(ominus(est[j], est[i]), ominus(gt[j], gt[i]))
        trans.append(np.linalg.norm(e[:3, 3]))
        rot.append(np.degrees(np.arccos(min(1, max(-1, (np.trace(e[:3, :3]) - 1) / 2)))))
    return np.sqrt(np.mean(np.square(trans))), np.sqrt(np.mean(np.square(rot)))


def test_rpe_matches_the_tum_formula_on_noisy_trajectories():
    gt = random_trajectory(100, seed=7)
    rng = np.random.default_rng(1)
    est = [T @ pose(Rotation.from_rotvec(rng.normal(0, 0.003, 3)).as_matrix(), rng.normal(0, 0.004, 3)) for T in gt]
    stamps = np.arange(100) * 33_333_333
    for delta in (1, 5):
        got = rpe(est, gt, stamps, delta_frames=delta)
        t_ref, r_ref = tum_rpe(est, gt, [(i, i + delta) for i in range(100 - delta)])
        assert got["n"] == 100 - delta
        assert got["trans_rmse"] == pytest.approx(t_ref, rel=1e-9)
        assert got["rot_rmse_deg"] == pytest.approx(r_ref, rel=1e-9)


def test_rpe_of_a_constant_drift_per_frame():
    gt = random_trajectory(60, seed=8)
    drift = pose(Rotation.from_euler("y", 0.2, degrees=True).as_matrix(), [0.003, 0.0, -0.004])  # 5 mm, 0.2 deg
    est = [gt[0]]
    for k in range(1, 60):
        # est_{k-1}^-1 est_k = drift @ (gt_{k-1}^-1 gt_k): the error E = (est motion)(true motion)^-1 is the drift
        est.append(est[-1] @ drift @ np.linalg.inv(gt[k - 1]) @ gt[k])
    got = rpe(est, gt, np.arange(60) * 10**8, delta_frames=1)
    assert got["n"] == 59
    assert got["trans_rmse"] == pytest.approx(0.005, rel=1e-9)
    assert got["trans_max"] == pytest.approx(0.005, rel=1e-9)
    assert got["rot_rmse_deg"] == pytest.approx(0.2, rel=1e-6)


def test_rpe_over_seconds_of_a_translational_drift():
    n, d = 90, np.array([0.001, 0.002, -0.002])  # 3 mm per frame, no rotation
    gt = [pose(np.eye(3), [0.01 * k, 0, 0]) for k in range(n)]
    est = [pose(np.eye(3), [0.01 * k, 0, 0] + k * d) for k in range(n)]
    stamps = np.arange(n) * 33_333_333 + 5  # 30 fps
    got = rpe(est, gt, stamps, delta_s=1.0)
    assert got["n"] == n - 30
    assert got["trans_mean"] == pytest.approx(30 * 0.003, rel=1e-9)
    assert got["rot_max_deg"] == pytest.approx(0.0, abs=1e-6)


def test_rpe_pairs_skip_frames_without_ground_truth():
    valid = np.array([1, 1, 1, 0, 1, 1], dtype=bool)
    assert rpe_pairs(np.arange(6), valid, 1, None) == [(0, 1), (1, 2), (4, 5)]
    gt = [np.eye(4) if v else None for v in valid]
    assert rpe(list(gt), gt, np.arange(6) * 10**9, delta_s=30.0)["trans_rmse"] is None


def test_associate_by_nearest_stamp_within_tolerance():
    est_ns = [0, 33_000_000, 66_000_000, 100_000_000]
    gt_ns = [1_000_000, 34_500_000, 90_000_000]  # third estimate has nothing within 20 ms
    gt = [pose(np.eye(3), [k, 0, 0]) for k in range(3)]
    _, _, gt_for = associate(est_ns, [np.eye(4)] * 4, gt_ns, gt, max_dt_s=0.02)
    assert [None if g is None else g[0, 3] for g in gt_for] == [0.0, 1.0, None, 2.0]
