"""Reading a calibration stack: a folder of 8-bit images and ``exposures.csv`` (header ``file,exposure``; one row
per image: its path relative to the folder and its exposure, any unit proportional to shutter time x gain).
``probeless scene bracket`` writes one from the synthetic rig; docs/cameras/radiometry.md says how to take one."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from probeless.errors import CalibrationError

EXPOSURES_CSV = "exposures.csv"


def read_stack(folder) -> tuple[list[np.ndarray], list[float], list[str]]:
    """(RGB uint8 images, exposures, file names) of a stack folder; CalibrationError naming the file and row."""
    import cv2

    folder = Path(folder)
    table = folder / EXPOSURES_CSV
    if not table.is_file():
        raise CalibrationError(f"{table}: not found (a stack folder holds the images and {EXPOSURES_CSV} with a "
                               f"header 'file,exposure')")
    with open(table, newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    if not rows or [c.strip() for c in rows[0][:2]] != ["file", "exposure"]:
        got = ",".join(rows[0]) if rows else ""
        raise CalibrationError(f"{table}: line 1: the header must be 'file,exposure', got {got!r}")
    images, exposures, names = [], [], []
    for line, row in enumerate(rows[1:], start=2):
        if not row or not "".join(row).strip():
            continue
        if len(row) < 2:
            raise CalibrationError(f"{table}: line {line}: expected 'file,exposure', got {','.join(row)!r}")
        name, value = row[0].strip(), row[1].strip()
        try:
            exposure = float(value)
        except ValueError:
            raise CalibrationError(f"{table}: line {line}: exposure {value!r} is not a number") from None
        if not (np.isfinite(exposure) and exposure > 0):
            raise CalibrationError(f"{table}: line {line}: exposure must be > 0, got {value}")
        path = folder / name
        image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if image is None:
            raise CalibrationError(f"{table}: line {line}: cannot read image {path}")
        if image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] != 3:
            raise CalibrationError(f"{path}: expected an 8-bit 3-channel image, got {image.shape} {image.dtype}")
        if images and image.shape != images[0].shape:
            raise CalibrationError(f"{path}: {image.shape[1]}x{image.shape[0]}, the stack's first image is "
                                   f"{images[0].shape[1]}x{images[0].shape[0]}")
        images.append(cv2.cvtColor(image, cv2.COLOR_BGR2RGB))
        exposures.append(exposure)
        names.append(name)
    if not images:
        raise CalibrationError(f"{table}: no image rows")
    return images, exposures, names


def write_stack(folder, stack: list[tuple[float, np.ndarray]]) -> Path:
    """Write (exposure, RGB uint8 image) pairs as ``frame_NNN.png`` and ``exposures.csv``; the CSV's path."""
    import cv2

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    rows = []
    for i, (exposure, image) in enumerate(stack):
        name = f"frame_{i:03d}.png"
        if not cv2.imwrite(str(folder / name), cv2.cvtColor(image, cv2.COLOR_RGB2BGR)):
            raise CalibrationError(f"could not write {folder / name}")
        rows.append((name, f"{exposure:.9g}"))
    path = folder / EXPOSURES_CSV
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(("file", "exposure"))
        w.writerows(rows)
    return path
