"""Shared checks of the benchmark smoke tests (tests/bench/test_bench_*.py)."""

from __future__ import annotations

import io
import json
import math
from contextlib import redirect_stdout
from typing import Callable


def positive(x) -> bool:
    """True for a finite number > 0 (not a bool): a timing or rate a benchmark must report."""
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and x > 0


def one_json_object(run: Callable[[], int]) -> dict:
    """Run a benchmark's ``main`` (``run()``, returning 0) and parse what it printed: exactly one JSON line."""
    buf = io.StringIO()
    with redirect_stdout(buf):
        assert run() == 0
    out = buf.getvalue()
    assert out.count("\n") == 1 and out.endswith("\n")  # exactly one JSON line
    return json.loads(out)
