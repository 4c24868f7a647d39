"""Parsing of the small text files of datasets (number tables, intrinsics), errors as ``file:line``."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from decimal import Decimal, InvalidOperation
from pathlib import Path
from typing import Iterator

import numpy as np

from probeless.datasets.base import Intrinsics
from probeless.errors import DatasetError


@dataclass(frozen=True)
class IntrinsicsOverride:
    """fx, fy, cx, cy given by the user [px]; all four or none."""

    fx: float | None = None
    fy: float | None = None
    cx: float | None = None
    cy: float | None = None

    @property
    def given(self) -> bool:
        values = (self.fx, self.fy, self.cx, self.cy)
        if any(v is not None for v in values) and not all(v is not None for v in values):
            missing = [n for n, v in zip(("fx", "fy", "cx", "cy"), values) if v is None]
            raise DatasetError(f"intrinsics override needs all of fx, fy, cx, cy; missing {missing}")
        return values[0] is not None

    def apply(self, width: int, height: int) -> Intrinsics:
        return Intrinsics(width, height, float(self.fx), float(self.fy), float(self.cx), float(self.cy))


def data_lines(path: Path) -> Iterator[tuple[int, list[str]]]:
    """(1-based line number, whitespace tokens) of each non-blank, non-``#`` line of a text file."""
    if not path.is_file():
        raise DatasetError(f"{path}: file is missing")
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise DatasetError(f"{path}: cannot read ({exc})") from exc
    for number, line in enumerate(text.splitlines(), start=1):
        line = line.strip()
        if line and not line.startswith("#"):
            yield number, line.replace(",", " ").split()


def parse_floats(tokens: list[str], path: Path, line: int, count: int | None = None) -> list[float]:
    """Tokens as finite floats; DatasetError ``file:line`` on text, NaN/inf or a wrong count."""
    if count is not None and len(tokens) != count:
        raise DatasetError(f"{path}:{line}: expected {count} numbers, got {len(tokens)}: {' '.join(tokens)!r}")
    try:
        values = [float(t) for t in tokens]
    except ValueError:
        raise DatasetError(f"{path}:{line}: unparsable number in {' '.join(tokens)!r}") from None
    if not all(math.isfinite(v) for v in values):
        raise DatasetError(f"{path}:{line}: NaN or inf in {' '.join(tokens)!r}")
    return values


def parse_stamp_ns(token: str, path: Path, line: int) -> int:
    """A stamp in seconds (``1305031102.175304``) as exact integer nanoseconds."""
    try:
        value = Decimal(token)
    except InvalidOperation:
        raise DatasetError(f"{path}:{line}: unparsable timestamp {token!r}") from None
    if not value.is_finite():
        raise DatasetError(f"{path}:{line}: timestamp {token!r} is not finite")
    return int(value * 1_000_000_000)


def read_matrix(path: Path, rows: int, cols: int) -> np.ndarray:
    """A whitespace-separated rows x cols matrix file (e.g. a 7-Scenes pose or intrinsics)."""
    lines = list(data_lines(path))
    if len(lines) != rows:
        raise DatasetError(f"{path}: expected {rows} rows of {cols} numbers, got {len(lines)} rows")
    return np.array([parse_floats(tokens, path, n, cols) for n, tokens in lines])


def read_stamps_file(path: Path) -> list[int]:
    """One stamp [s] per line -> ns, strictly increasing."""
    stamps: list[int] = []
    for n, tokens in data_lines(path):
        if len(tokens) != 1:
            raise DatasetError(f"{path}:{n}: expected one timestamp [s] per line, got {' '.join(tokens)!r}")
        stamp = parse_stamp_ns(tokens[0], path, n)
        if stamps and stamp <= stamps[-1]:
            raise DatasetError(f"{path}:{n}: timestamp {tokens[0]} is not after the previous one")
        stamps.append(stamp)
    return stamps


def read_open3d_intrinsics(path: Path) -> tuple[Intrinsics, dict]:
    """Open3D ``PinholeCameraIntrinsic`` JSON (column-major ``intrinsic_matrix``) and the whole object."""
    try:
        obj = json.loads(path.read_text())
        w, h = int(obj["width"]), int(obj["height"])
        m = [float(v) for v in obj["intrinsic_matrix"]]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise DatasetError(f"{path}: not an Open3D intrinsics JSON (width, height, intrinsic_matrix): {exc}") from exc
    if len(m) != 9 or not all(math.isfinite(v) for v in m):
        raise DatasetError(f"{path}: intrinsic_matrix must hold 9 finite numbers")
    return Intrinsics(w, h, m[0], m[4], m[6], m[7]), obj


def write_open3d_intrinsics(path: Path, intr: Intrinsics) -> None:
    """Write ``intr`` as Open3D ``PinholeCameraIntrinsic`` JSON."""
    matrix = [intr.fx, 0.0, 0.0, 0.0, intr.fy, 0.0, intr.cx, intr.cy, 1.0]
    path.write_text(json.dumps({"width": intr.width, "height": intr.height, "intrinsic_matrix": matrix}, indent=1))


def find_intrinsics_json(root: Path) -> Path | None:
    """The one JSON file of ``root`` holding an ``intrinsic_matrix``; DatasetError when several do."""
    found = []
    for p in sorted(root.glob("*.json")):
        try:
            if "intrinsic_matrix" in json.loads(p.read_text()):
                found.append(p)
        except (OSError, ValueError):
            continue
    if len(found) > 1:
        raise DatasetError(f"{root}: several intrinsics JSON files {[p.name for p in found]}; keep one")
    return found[0] if found else None
