"""The radiometric camera model: inverse response, vignetting and white balance, in one YAML file that
``probeless calibrate response|vignetting`` write and a graph is to take as ``radiometry:=FILE``
(docs/cameras/radiometry.md).

File (every block but ``response`` optional)::

    radiometry: 1                        # format version
    response:                            # linear signal (1 = full well) of every 8-bit code, per channel
      inverse: {r: [256 numbers], g: [...], b: [...]}   # increasing, 0 at code 0, 1 at code 255
      valid_codes: [lo, hi]              # codes the exposure stack measured; outside: extrapolated
    vignetting:                          # relative illumination V = 1 + k1 r^2 + k2 r^4 + k3 r^6
      model: poly
      coeffs: [k1, k2, k3]               # 1 to 3 numbers
      center: [cx, cy]                   # [px] in an image of width x height
      width: W
      height: H                          # r: distance from center / half the diagonal between corner pixel centres
    white_balance:
      gains: [r, g, b]                   # the camera's channel gains relative to green (g = 1)

Linear radiance in the camera's units is ``inverse[c][code] / (exposure * gains[c] * V)``
(:meth:`Radiometry.linear`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from probeless.errors import CalibrationError

FORMAT_VERSION = 1
CHANNELS = ("r", "g", "b")


@dataclass(frozen=True)
class Vignetting:
    """``V = 1 + k1 r^2 + k2 r^4 + k3 r^6``, r from ``center`` in half diagonals of a ``width`` x ``height`` image."""

    coeffs: tuple[float, ...]
    center: tuple[float, float]
    width: int
    height: int

    def factor(self, width: int | None = None, height: int | None = None) -> np.ndarray:
        """(H, W) relative illumination for an image of ``width`` x ``height`` (default the calibrated size; another
        size of the same sensor scales the centre with the image)."""
        w, h = width or self.width, height or self.height
        cx = (self.center[0] + 0.5) * w / self.width - 0.5
        cy = (self.center[1] + 0.5) * h / self.height - 0.5
        v, u = np.mgrid[0:h, 0:w].astype(np.float64)
        r2 = ((u - cx) ** 2 + (v - cy) ** 2) / (0.25 * ((w - 1) ** 2 + (h - 1) ** 2))
        return 1.0 + sum(k * r2 ** (i + 1) for i, k in enumerate(self.coeffs))


@dataclass(frozen=True)
class Radiometry:
    """A camera's calibrated radiometry (module doc)."""

    inverse: np.ndarray                       # (3, 256) linear signal per code, 1 at 255
    valid_codes: tuple[int, int] = (0, 255)
    vignetting: Vignetting | None = None
    gains: np.ndarray | None = None           # (3,) white balance relative to green

    def linearise(self, image: np.ndarray) -> np.ndarray:
        """(H, W, 3) float32 linear signal of an (H, W, 3) uint8 image (1 = full well)."""
        if image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] != 3:
            raise CalibrationError(f"radiometry: expected an (H, W, 3) uint8 image, got {image.shape} {image.dtype}")
        return np.stack([self.inverse[c].astype(np.float32)[image[..., c]] for c in range(3)], axis=-1)

    def linear(self, image: np.ndarray, exposure: float = 1.0) -> np.ndarray:
        """(H, W, 3) float32 relative radiance: linearised, divided by ``exposure``, white balance and vignetting."""
        out = self.linearise(image) / np.float32(exposure)
        if self.gains is not None:
            out /= self.gains.astype(np.float32)
        if self.vignetting is not None:
            v = self.vignetting.factor(image.shape[1], image.shape[0]).astype(np.float32)
            out /= np.maximum(v, np.float32(1e-3))[..., None]
        return out


def _err(path, key: str, what: str) -> CalibrationError:
    return CalibrationError(f"{path}: key '{key}': {what}")


def _numbers(value, path, key: str, n: int | None = None) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise _err(path, key, f"expected a list of numbers, got {value!r:.60}") from None
    if arr.ndim != 1 or (n is not None and len(arr) != n) or not np.isfinite(arr).all():
        want = f"{n} finite numbers" if n is not None else "a list of finite numbers"
        raise _err(path, key, f"expected {want}, got {arr.shape[0] if arr.ndim == 1 else arr.shape} value(s)")
    return arr


def parse_radiometry(data, path) -> Radiometry:
    """A :class:`Radiometry` of a loaded YAML mapping; CalibrationError naming ``path`` and the key at fault."""
    if not isinstance(data, dict):
        raise CalibrationError(f"{path}: a radiometry file is a mapping, got {type(data).__name__}")
    if data.get("radiometry") != FORMAT_VERSION:
        raise _err(path, "radiometry", f"format version must be {FORMAT_VERSION}, got {data.get('radiometry')!r}")
    resp = data.get("response")
    if not isinstance(resp, dict) or not isinstance(resp.get("inverse"), dict):
        raise _err(path, "response.inverse", "missing (run `probeless calibrate response` first)")
    curves = []
    for c in CHANNELS:
        key = f"response.inverse.{c}"
        if c not in resp["inverse"]:
            raise _err(path, key, "missing")
        curve = _numbers(resp["inverse"][c], path, key, 256)
        if np.any(np.diff(curve) < 0) or abs(curve[0]) > 1e-9 or abs(curve[255] - 1.0) > 1e-6:
            raise _err(path, key, "must be non-decreasing from 0 at code 0 to 1 at code 255")
        curves.append(curve)
    valid = _numbers(resp.get("valid_codes", [0, 255]), path, "response.valid_codes", 2)
    if not 0 <= valid[0] < valid[1] <= 255:
        raise _err(path, "response.valid_codes", f"expected 0 <= lo < hi <= 255, got {valid.tolist()}")
    vig = None
    if data.get("vignetting") is not None:
        vig = _vignetting(data["vignetting"], path)
    gains = None
    if data.get("white_balance") is not None:
        wb = data["white_balance"]
        if not isinstance(wb, dict):
            raise _err(path, "white_balance", "expected a mapping with 'gains'")
        gains = _numbers(wb.get("gains"), path, "white_balance.gains", 3)
        if np.any(gains <= 0):
            raise _err(path, "white_balance.gains", f"must be > 0, got {gains.tolist()}")
    return Radiometry(np.stack(curves), (int(valid[0]), int(valid[1])), vig, gains)


def _vignetting(v, path) -> Vignetting:
    if not isinstance(v, dict):
        raise _err(path, "vignetting", "expected a mapping (model, coeffs, center, width, height)")
    if v.get("model") != "poly":
        raise _err(path, "vignetting.model", f"only 'poly' is supported, got {v.get('model')!r}")
    coeffs = _numbers(v.get("coeffs"), path, "vignetting.coeffs")
    if not 1 <= len(coeffs) <= 3:
        raise _err(path, "vignetting.coeffs", f"1 to 3 coefficients [k1, k2, k3], got {len(coeffs)}")
    center = _numbers(v.get("center"), path, "vignetting.center", 2)
    size = []
    for key in ("width", "height"):
        val = v.get(key)
        if not isinstance(val, int) or isinstance(val, bool) or val < 2:
            raise _err(path, f"vignetting.{key}", f"expected an integer >= 2 [px], got {val!r}")
        size.append(val)
    return Vignetting(tuple(coeffs.tolist()), (float(center[0]), float(center[1])), size[0], size[1])


def load_radiometry(path) -> Radiometry:
    """Read and validate a radiometry file (module doc); CalibrationError naming the file and key at fault."""
    import yaml

    try:
        with open(path, encoding="utf-8") as f:
            data = yaml.safe_load(f)
    except (OSError, yaml.YAMLError) as exc:
        raise CalibrationError(f"{path}: cannot read the radiometry file: {exc}") from None
    return parse_radiometry(data, path)


def radiometry_dict(r: Radiometry, extra: dict | None = None) -> dict:
    """The YAML mapping of ``r`` (plus ``extra`` keys, e.g. the calibration reports)."""
    data: dict = {"radiometry": FORMAT_VERSION,
                  "response": {"inverse": {c: [round(float(x), 8) for x in r.inverse[i]]
                                           for i, c in enumerate(CHANNELS)},
                               "valid_codes": [int(r.valid_codes[0]), int(r.valid_codes[1])]}}
    if r.vignetting is not None:
        v = r.vignetting
        data["vignetting"] = {"model": "poly", "coeffs": [float(k) for k in v.coeffs],
                              "center": [float(v.center[0]), float(v.center[1])], "width": int(v.width),
                              "height": int(v.height)}
    if r.gains is not None:
        data["white_balance"] = {"gains": [float(g) for g in r.gains]}
    data.update(extra or {})
    return data


def save_radiometry(path, r: Radiometry, extra: dict | None = None) -> None:
    """Write ``r`` as YAML (validated by reading it back: a file this writes always loads)."""
    import yaml

    data = radiometry_dict(r, extra)
    parse_radiometry(data, path)
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", encoding="utf-8") as f:
        yaml.safe_dump(data, f, sort_keys=False, default_flow_style=None, width=120)
