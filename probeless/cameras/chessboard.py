"""Chessboard corners: board sizes, detection in real (fisheye) images, overlays.

The board is given as Bouguet's and Scaramuzza's (OCamCalib) toolboxes count it, and as data sets
made with them document it: the squares spanned by the grid of inner corners, so a "5 x 7" board
has 6 x 8 inner corners (the points that are detected) and 7 x 9 squares printed in all.

Corners are found with cv2.findChessboardCornersSB (with CALIB_CB_LARGER, so a board larger than
the one given is recognised and reported instead of yielding a wrong subset), falling back to
cv2.findChessboardCorners + cornerSubPix.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from probeless.errors import CalibrationError


@dataclass(frozen=True)
class BoardDetection:
    """The inner corners found in one image, or why none were."""

    name: str
    corners: np.ndarray | None      # (N, 2) float64 (u, v), row-major over ``grid``
    grid: tuple[int, int] = (0, 0)  # (corners per row, rows) of ``corners``; for a mismatch, the board found
    reason: str = ""                # why ``corners`` is None
    size: tuple[int, int] = (0, 0)  # image (width, height)


def parse_board(text: str) -> tuple[int, int]:
    """``"5x7"`` (squares between inner corners) -> inner corners (6, 8); CalibrationError when malformed."""
    m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text)
    if not m or min(int(m.group(1)), int(m.group(2))) < 1:
        raise CalibrationError(f"--board {text!r}: expected COLSxROWS squares between the inner corners, "
                               f"each at least 1 (e.g. 5x7 for a board with 6x8 inner corners)")
    return int(m.group(1)) + 1, int(m.group(2)) + 1


def board_points(grid: tuple[int, int], square_m: float) -> np.ndarray:
    """(N, 3) float64 corner positions on the board plane (z = 0), row-major, in metres."""
    w, h = grid
    xs, ys = np.meshgrid(np.arange(w), np.arange(h))
    return np.stack([xs.ravel(), ys.ravel(), np.zeros(w * h)], axis=1) * float(square_m)


def detect_board(gray: np.ndarray, inner: tuple[int, int], name: str = "") -> BoardDetection:
    """Inner corners of a ``inner`` = (cols, rows) board in a grey image (either orientation)."""
    size = (gray.shape[1], gray.shape[0])
    flags = cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY | cv2.CALIB_CB_LARGER
    ok, corners, meta = cv2.findChessboardCornersSBWithMeta(gray, inner, flags)
    if ok and meta is not None:
        rows, cols = meta.shape
        if sorted((cols, rows)) == sorted(inner):
            return BoardDetection(name, corners.reshape(-1, 2).astype(np.float64), (cols, rows), size=size)
        if (cols >= inner[0] and rows >= inner[1]) or (cols >= inner[1] and rows >= inner[0]):
            return BoardDetection(name, None, (cols, rows), f"board has at least {cols}x{rows} inner corners "
                                  f"(--board {cols - 1}x{rows - 1}), more than the {inner[0]}x{inner[1]} expected",
                                  size)
    ok, corners = cv2.findChessboardCorners(gray, inner, flags=cv2.CALIB_CB_ADAPTIVE_THRESH
                                            | cv2.CALIB_CB_NORMALIZE_IMAGE)
    if not ok:
        return BoardDetection(name, None, reason="board not found", size=size)
    corners = cv2.cornerSubPix(gray, corners, (5, 5), (-1, -1),
                               (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 0.01))
    return BoardDetection(name, corners.reshape(-1, 2).astype(np.float64), tuple(inner), size=size)


def image_names(paths: Sequence[str]) -> list[str]:
    """Image paths relative to their common folder (just the file names when they share one)."""
    full = [os.path.abspath(p) for p in paths]
    common = os.path.commonpath([os.path.dirname(p) for p in full]) if full else ""
    return [os.path.relpath(p, common).replace(os.sep, "/") for p in full]


def detect_images(paths: Sequence[str], inner: tuple[int, int],
                  on_image: Callable[[BoardDetection], None] | None = None) -> list[BoardDetection]:
    """Detect the board in every image file; unreadable files become detections with a reason."""
    out = []
    for path, name in zip(paths, image_names(paths)):
        gray = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        det = (BoardDetection(name, None, reason="cannot read the image") if gray is None
               else detect_board(gray, inner, name))
        out.append(det)
        if on_image is not None:
            on_image(det)
    return out


def draw_overlay(image: np.ndarray, detected: np.ndarray, reprojected: np.ndarray, label: str = "") -> np.ndarray:
    """BGR copy of ``image`` with detected corners (green circles) and reprojected ones (red crosses)."""
    out = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR) if image.ndim == 2 else image.copy()
    for d, r in zip(np.rint(detected).astype(int), np.rint(reprojected).astype(int)):
        cv2.circle(out, (int(d[0]), int(d[1])), 6, (0, 255, 0), 1, cv2.LINE_AA)
        cv2.drawMarker(out, (int(r[0]), int(r[1])), (0, 0, 255), cv2.MARKER_CROSS, 8, 1, cv2.LINE_AA)
    if label:
        cv2.putText(out, label, (10, 45), cv2.FONT_HERSHEY_SIMPLEX, 0.7, (0, 0, 255), 2, cv2.LINE_AA)
    return out
