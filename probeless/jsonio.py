"""The one JSON helper: make results JSON-safe (non-finite floats -> null) and print one JSON object."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from typing import Any, TextIO

import numpy as np


def json_safe(obj: Any, places: int | None = None) -> Any:
    """``obj`` with every float finite or ``None``, recursively through dicts, lists and tuples.

    numpy scalars and arrays become Python numbers and lists, paths become strings; with ``places``
    floats are rounded to that many decimals.
    """
    if isinstance(obj, (float, np.floating)):
        x = float(obj)
        if not math.isfinite(x):
            return None
        return round(x, places) if places is not None else x
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.ndarray):
        return json_safe(obj.tolist(), places)
    if isinstance(obj, dict):
        return {k: json_safe(v, places) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v, places) for v in obj]
    if isinstance(obj, Path):
        return str(obj)
    return obj


def dumps(obj: Any, places: int | None = None, **kwargs: Any) -> str:
    """``json.dumps`` of :func:`json_safe` (``NaN`` never reaches the text)."""
    return json.dumps(json_safe(obj, places), allow_nan=False, **kwargs)


def print_json(obj: Any, places: int | None = None, stream: TextIO | None = None) -> None:
    """Exactly one JSON object on one line (stdout by default), flushed."""
    out = stream or sys.stdout
    out.write(dumps(obj, places) + "\n")
    out.flush()
