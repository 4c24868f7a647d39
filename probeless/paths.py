"""Where the repository and the shared data live (one copy of these paths).

``REPO_ROOT`` is the checkout this package runs from (``pip install -e .``): launch graphs, scenes
and meshes that the defaults name are looked up there. ``SHARED_DATA`` is the data folder beside
the checkout (``../shared/data``); ``PROBELESS_SHARED_DATA`` overrides it.
"""

from __future__ import annotations

import os
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("PROBELESS_SHARED_DATA", REPO_ROOT.parent / "shared" / "data"))


def repo_path(path: str | Path) -> Path:
    """``path`` as given when it exists (or is absolute), else the repository's file of that name."""
    p = Path(path)
    if p.is_absolute() or p.exists() or not (REPO_ROOT / p).exists():
        return p
    return REPO_ROOT / p
