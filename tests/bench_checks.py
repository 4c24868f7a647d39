"""Shared checks of the benchmark smoke tests (tests/test_bench_*.py)."""

from __future__ import annotations

import math


def positive(x) -> bool:
    """True for a finite number > 0 (not a bool): a timing or rate a benchmark must report."""
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and x > 0
