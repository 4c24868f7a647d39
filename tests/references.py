"""Independent reference implementations the tests compare against."""

import numpy as np
from scipy.spatial.transform import Rotation


def horn_quaternion(model: np.ndarray, data: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Horn (1987), "Closed-form solution of absolute orientation using unit quaternions": the rotation is the
    eigenvector of the largest eigenvalue of the symmetric 4x4 matrix N built from M = sum model_c data_c^T;
    the translation maps the model centroid onto the data centroid. Returns (R, t) with data ~ R model + t."""
    mc, dc = model.mean(0), data.mean(0)
    M = (model - mc).T @ (data - dc)
    (sxx, sxy, sxz), (syx, syy, syz), (szx, szy, szz) = M
    N = np.array([
        [sxx + syy + szz, syz - szy, szx - sxz, sxy - syx],
        [syz - szy, sxx - syy - szz, sxy + syx, szx + sxz],
        [szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy],
        [sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz]])
    w, v = np.linalg.eigh(N)
    q0, qx, qy, qz = v[:, np.argmax(w)]
    R = Rotation.from_quat([qx, qy, qz, q0]).as_matrix()  # scipy is scalar-last
    return R, dc - R @ mc
