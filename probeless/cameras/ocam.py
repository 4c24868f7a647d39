"""Scaramuzza's OCamCalib polynomial model, with the conventions of OCamCalib's calib_results.txt.

OCamCalib's own frame: x along image rows (down), y along columns (right), z = -optical axis
(pol[0] < 0 makes the centre pixel look along -z). So an OpenCV-frame point (X, Y, Z) is
(x, y, z) = (Y, X, -Z) for OCamCalib. With the centre (xc, yc) = (row, col), affine (c, d, e):

* cam2world (unproject): [xp, yp] = A^-1 [row - xc, col - yc] with A = [[c, d], [e, 1]],
  rho = |(xp, yp)|, ray = (xp, yp, pol(rho)) normalised;
* world2cam (project): theta = atan(z / |(x, y)|), rho = invpol(theta),
  (x', y') = rho (x, y) / |(x, y)|, row = c x' + d y' + xc, col = e x' + y' + yc.

Pixels are 0-based (OCamCalib's "C convention"), i.e. OpenCV's pixel-centre convention.
The domain is the cone of rays seen within the image: radius up to the farthest image corner
(clipped where the ray angle stops increasing with rho).
"""

from __future__ import annotations

import numpy as np

from probeless.cameras.base import CameraModel, as_pixels, as_points, camera_matrix, header, invalidate, normalize_rows
from probeless.errors import CalibrationError
from probeless.messages.sensor import CameraInfo


def polyval_ascending(coeffs: np.ndarray, x: np.ndarray) -> np.ndarray:
    """sum_k coeffs[k] x^k (Horner), as OCamCalib stores its polynomials."""
    out = np.zeros_like(x) + coeffs[-1]
    for c in coeffs[-2::-1]:
        out = out * x + c
    return out


class OcamModel(CameraModel):
    """OCamCalib camera: poly (cam2world), invpoly (world2cam), centre (row, col), affine (c, d, e)."""

    model = "ocam"

    def __init__(self, width: int, height: int, poly: np.ndarray, invpoly: np.ndarray,
                 center: np.ndarray, affine: np.ndarray = (1.0, 0.0, 0.0)):
        self.width, self.height = int(width), int(height)
        self.poly = np.array(poly, dtype=np.float64).ravel()
        self.invpoly = np.array(invpoly, dtype=np.float64).ravel()
        self.xc, self.yc = (float(v) for v in np.ravel(center))
        self.c, self.d, self.e = (float(v) for v in np.ravel(affine))
        if len(self.poly) == 0 or len(self.invpoly) == 0 or self.poly[0] == 0:
            raise CalibrationError("ocam model needs non-empty poly and invpoly with poly[0] != 0")
        if self.c - self.d * self.e == 0:
            raise CalibrationError(f"ocam affine (c, d, e) = ({self.c}, {self.d}, {self.e}) is singular")
        self.rho_max, self.theta_max = self._domain()

    @classmethod
    def from_camera_info(cls, info: CameraInfo) -> OcamModel:
        """The model of an ``ocam`` CameraInfo."""
        return cls(info.width, info.height, info.ocam_poly, info.ocam_invpoly, info.ocam_center, info.ocam_affine)

    def _axis_angle(self, rho: np.ndarray) -> np.ndarray:
        """Angle from the optical axis of the ray at sensor radius ``rho`` (cam2world)."""
        return np.arctan2(rho, -polyval_ascending(self.poly, rho))

    def _domain(self) -> tuple[float, float]:
        """(rho_max, theta_max): sensor radius of the farthest image corner, clipped to monotonic angles."""
        corners = np.array([[-0.5, -0.5], [self.width - 0.5, -0.5], [-0.5, self.height - 0.5],
                            [self.width - 0.5, self.height - 0.5]])
        rho_corner = np.hypot(*self._sensor(corners).T).max()
        rho = np.linspace(0, rho_corner, 4001)
        angle = self._axis_angle(rho)
        bad = np.nonzero(np.diff(angle) <= 0)[0]
        end = len(rho) - 1 if len(bad) == 0 else int(bad[0])
        return float(rho[end]), float(angle[end])

    def _sensor(self, uv: np.ndarray) -> np.ndarray:
        """Pixels (u, v) -> affine-corrected sensor coordinates (xp, yp) in the OCamCalib frame."""
        dr, dc = uv[:, 1] - self.xc, uv[:, 0] - self.yc
        inv_det = 1.0 / (self.c - self.d * self.e)
        return np.column_stack([inv_det * (dr - self.d * dc), inv_det * (-self.e * dr + self.c * dc)])

    def unproject(self, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        s = self._sensor(as_pixels(pixels))
        rho = np.hypot(s[:, 0], s[:, 1])
        z = polyval_ascending(self.poly, rho)
        rays = normalize_rows(np.column_stack([s[:, 1], s[:, 0], -z]))  # OCamCalib (x, y, z) -> (y, x, -z)
        valid = (rho <= self.rho_max) & np.isfinite(rays).all(axis=1)
        return invalidate(rays, valid), valid

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        p = as_points(points)
        x, y, z = p[:, 1], p[:, 0], -p[:, 2]  # OpenCV -> OCamCalib frame
        norm = np.hypot(x, y)
        valid = (np.arctan2(norm, -z) <= self.theta_max) & ((norm > 0) | (z < 0))
        with np.errstate(all="ignore"):
            theta = np.arctan2(z, norm)  # = atan(z / norm) for norm > 0
            scale = np.where(norm > 0, polyval_ascending(self.invpoly, theta) / norm, 0.0)
        xs, ys = x * scale, y * scale
        row = self.c * xs + self.d * ys + self.xc
        col = self.e * xs + ys + self.yc
        return invalidate(np.column_stack([col, row]), valid), valid

    def nominal_K(self) -> np.ndarray:
        """A pinhole K with the focal length at the image centre (|pol[0]|) and the OCam centre."""
        f = abs(self.poly[0])
        return camera_matrix(f, f, self.yc, self.xc)

    def to_camera_info(self, frame_id: str = "", stamp_ns: int = 0) -> CameraInfo:
        return CameraInfo(header(frame_id, stamp_ns), self.width, self.height, "ocam", self.nominal_K(),
                          ocam_poly=self.poly.copy(), ocam_invpoly=self.invpoly.copy(),
                          ocam_affine=np.array([self.c, self.d, self.e]),
                          ocam_center=np.array([self.xc, self.yc]))


def parse_calib_results(text: str, path: str, width: int | None = None, height: int | None = None) -> dict:
    """CameraInfo fields from the text of an OCamCalib calib_results.txt.

    Its non-comment lines are: "n a0 .. a_{n-1}" (pol), "m b0 .. b_{m-1}" (invpol), "xc yc",
    "c d e", and optionally "height width". See :func:`probeless.cameras.io.load_calibration` for
    how a missing size is resolved. CalibrationError names the file and line at fault.
    """
    rows: list[tuple[int, list[float]]] = []
    for number, line in enumerate(text.splitlines(), 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        try:
            rows.append((number, [float(t) for t in line.split()]))
        except ValueError:
            raise CalibrationError(f"{path}:{number}: OCamCalib file: expected numbers, got {line!r}") from None
    names = ("polynomial (pol)", "inverse polynomial (invpol)", "centre (xc yc)", "affine (c d e)", "image size")
    if not 4 <= len(rows) <= 5:
        raise CalibrationError(f"{path}: OCamCalib file: expected 4 or 5 data lines ({', '.join(names)}), "
                               f"found {len(rows)}")
    polys = []
    for (number, values), name in zip(rows[:2], names):
        if not values or values[0] != int(values[0]) or int(values[0]) != len(values) - 1 or len(values) < 2:
            raise CalibrationError(f"{path}:{number}: OCamCalib {name}: the first number must be the count of "
                                   f"coefficients that follow, got {values[:1]} with {len(values) - 1}")
        polys.append(np.array(values[1:]))
    for (number, values), name, count in zip(rows[2:], names[2:], (2, 3, 2)):
        if len(values) != count:
            raise CalibrationError(f"{path}:{number}: OCamCalib {name}: expected {count} numbers, got {len(values)}")
    xc, yc = rows[2][1]
    if len(rows) == 5:
        number, (h, w) = rows[4]
        if h != int(h) or w != int(w) or h <= 0 or w <= 0:
            raise CalibrationError(f"{path}:{number}: OCamCalib image size: expected two positive integers")
        for name, stated, want in (("width", int(w), width), ("height", int(h), height)):
            if want is not None and want != stated:
                raise CalibrationError(f"{path}:{number}: OCamCalib image {name} is {stated}, caller expects {want}")
        width, height = int(w), int(h)
    width = width if width is not None else int(round(2 * yc + 1))
    height = height if height is not None else int(round(2 * xc + 1))
    return {"model": "ocam", "width": width, "height": height, "ocam_poly": polys[0], "ocam_invpoly": polys[1],
            "ocam_center": np.array([xc, yc]), "ocam_affine": np.array(rows[3][1])}
