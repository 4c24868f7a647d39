"""Calibration files: our YAML, and OCamCalib's calib_results.txt (read only).

Our YAML (``save_calibration`` writes it)::

    model: omnidir            # pinhole | omnidir | kannala_brandt | ocam
    width: 1024
    height: 1024
    K: [[fx, s, cx], [0, fy, cy], [0, 0, 1]]
    D: [k1, k2, p1, p2]       # per model, see CameraInfo; may be empty
    xi: 1.0                   # omnidir only (required there)
    ocam_poly: [...]          # ocam only: the four ocam_* fields (K is optional for ocam)
    ocam_invpoly: [...]
    ocam_affine: [c, d, e]
    ocam_center: [xc, yc]     # (row, col)
    rms_px: 0.31              # metadata: any keys listed in extra_keys, ignored by the loader
    extra_keys: [rms_px]

Any other key is an error. The file type is detected by content: a file whose first
non-comment line is all numbers is an OCamCalib calib_results.txt.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np
import yaml

from probeless.cameras.ocam import parse_calib_results
from probeless.errors import CalibrationError, SchemaError
from probeless.messages.header import Header
from probeless.messages.sensor import CameraInfo

_FIELDS = {
    "pinhole": {"K", "D"},
    "omnidir": {"K", "D", "xi"},
    "kannala_brandt": {"K", "D"},
    "ocam": {"K", "D", "ocam_poly", "ocam_invpoly", "ocam_affine", "ocam_center"},
}
_REQUIRED = {"pinhole": {"K"}, "omnidir": {"K", "xi"}, "kannala_brandt": {"K"},
             "ocam": {"ocam_poly", "ocam_invpoly", "ocam_center"}}
_BASE_KEYS = ("model", "width", "height")


def load_calibration(path: str | os.PathLike, width: int | None = None, height: int | None = None,
                     frame_id: str = "") -> CameraInfo:
    """Read a calibration file (our YAML or OCamCalib calib_results.txt) as a CameraInfo.

    ``width``/``height`` matter only for OCamCalib files, which may not state the image size:
    the size line of the file wins when present (an override that disagrees is an error); without
    one the overrides are used, else the size is inferred as round(2 * centre + 1), i.e. assuming
    the centre is the middle of the image (only approximate: check it). For YAML files an override
    that disagrees with the file is an error.
    """
    path = os.fspath(path)
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except OSError as exc:
        raise CalibrationError(f"{path}: cannot read calibration file: {exc.strerror or exc}") from exc
    if _looks_like_ocam(text):
        fields = parse_calib_results(text, path, width, height)
    else:
        fields = _parse_yaml(text, path)
        for key, want in (("width", width), ("height", height)):
            if want is not None and want != fields[key]:
                raise CalibrationError(f"{path}: key '{key}': file says {fields[key]}, caller expects {want}")
    if fields["model"] == "ocam" and "K" not in fields:
        fields["K"] = _ocam_nominal_K(fields)
    try:
        return CameraInfo(Header(0, frame_id), **fields)
    except SchemaError as exc:
        raise CalibrationError(f"{path}: {exc}") from exc


def load_calibration_extra(path: str | os.PathLike) -> dict[str, Any]:
    """The metadata keys (those listed in ``extra_keys``) of one of our YAML calibration files."""
    path = os.fspath(path)
    with open(path, encoding="utf-8") as f:
        data = _read_yaml_mapping(f.read(), path)[0]
    return {k: data[k] for k in data.get("extra_keys", [])}


def save_calibration(path: str | os.PathLike, info: CameraInfo, extra: dict[str, Any] | None = None) -> None:
    """Write ``info`` as our YAML, with ``extra`` metadata keys (e.g. rms_px, images_used) listed in extra_keys."""
    data: dict[str, Any] = {"model": info.model, "width": int(info.width), "height": int(info.height),
                            "K": _floats(info.K), "D": _floats(info.D)}
    if info.model == "omnidir":
        data["xi"] = float(info.xi)
    if info.model == "ocam":
        for key in ("ocam_poly", "ocam_invpoly", "ocam_affine", "ocam_center"):
            data[key] = _floats(getattr(info, key))
    extra = dict(extra or {})
    clash = sorted(set(extra) & (set(data) | set(_FIELDS["ocam"]) | {"xi", "extra_keys"}))
    if clash:
        raise CalibrationError(f"{path}: extra metadata keys {clash} collide with calibration keys")
    if extra:
        data.update({k: _plain(v) for k, v in extra.items()})
        data["extra_keys"] = sorted(extra)
    with open(os.fspath(path), "w", encoding="utf-8") as f:
        yaml.safe_dump(data, f, sort_keys=False, default_flow_style=None)


def _plain(value: Any) -> Any:
    """numpy scalars and arrays (also inside lists and dicts) as plain Python values, for YAML."""
    if isinstance(value, (np.ndarray, np.generic)):
        return value.tolist()
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def _floats(a: np.ndarray) -> list:
    return np.asarray(a, dtype=np.float64).tolist()


def _looks_like_ocam(text: str) -> bool:
    for line in text.splitlines():
        line = line.strip()
        if line and not line.startswith("#"):
            try:
                [float(t) for t in line.split()]
                return True
            except ValueError:
                return False
    return False


def _ocam_nominal_K(fields: dict) -> np.ndarray:
    f = abs(float(fields["ocam_poly"][0])) or 1.0
    xc, yc = fields["ocam_center"]
    return np.array([[f, 0, yc], [0, f, xc], [0, 0, 1]], dtype=np.float64)


def _read_yaml_mapping(text: str, path: str) -> tuple[dict, dict[str, int]]:
    """(mapping, key -> 1-based line) of a YAML document; CalibrationError when it is not a mapping."""
    try:
        node = yaml.compose(text)
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"{path}:{mark.line + 1}" if mark else path
        raise CalibrationError(f"{where}: invalid YAML: {getattr(exc, 'problem', exc)}") from exc
    if not isinstance(data, dict):
        raise CalibrationError(f"{path}: a calibration file must be a YAML mapping with a 'model' key")
    lines = {k.value: k.start_mark.line + 1 for k, _ in node.value} if isinstance(node, yaml.MappingNode) else {}
    return data, lines


def _parse_yaml(text: str, path: str) -> dict:
    data, lines = _read_yaml_mapping(text, path)

    def fail(key: str, why: str) -> CalibrationError:
        where = f"{path}:{lines[key]}" if key in lines else path
        return CalibrationError(f"{where}: key '{key}': {why}")

    model = data.get("model")
    if model not in _FIELDS:
        raise fail("model", f"must be one of {sorted(_FIELDS)}, got {model!r}")
    extra_keys = data.get("extra_keys", [])
    if not (isinstance(extra_keys, list) and all(isinstance(k, str) for k in extra_keys)):
        raise fail("extra_keys", "must be a list of key names")
    allowed = set(_BASE_KEYS) | _FIELDS[model] | set(extra_keys) | {"extra_keys"}
    for key in data:
        if key not in allowed:
            raise fail(str(key), f"unknown key for model {model!r}; allowed: {sorted(allowed - {'extra_keys'})}")
    for key in (*_BASE_KEYS, *sorted(_REQUIRED[model])):
        if key not in data:
            raise fail(key, "missing")
    fields: dict[str, Any] = {"model": model}
    for key in ("width", "height"):
        if not isinstance(data[key], int) or isinstance(data[key], bool) or data[key] <= 0:
            raise fail(key, f"must be a positive integer, got {data[key]!r}")
        fields[key] = data[key]
    shapes = {"K": (3, 3), "D": (-1,), "ocam_poly": (-1,), "ocam_invpoly": (-1,), "ocam_affine": (3,),
              "ocam_center": (2,)}
    for key, shape in shapes.items():
        if key in data:
            fields[key] = _array(data[key], shape, lambda why, k=key: fail(k, why))
    if "xi" in data:
        if not isinstance(data["xi"], (int, float)) or isinstance(data["xi"], bool):
            raise fail("xi", f"must be a number, got {data['xi']!r}")
        fields["xi"] = float(data["xi"])
    return fields


def _array(value: Any, shape: tuple[int, ...], fail) -> np.ndarray:
    try:
        a = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise fail(f"must be numbers, got {value!r}") from None
    if a.ndim != len(shape) or any(s not in (-1, n) for s, n in zip(shape, a.shape)):
        want = "a list" if shape == (-1,) else "x".join(map(str, shape))
        raise fail(f"must be {want} of numbers, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise fail("must be finite numbers")
    return a
