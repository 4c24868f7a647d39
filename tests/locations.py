"""Where the tests find the repository, their own files and the shared data (tests live one folder down)."""

from pathlib import Path

from probeless.paths import REPO_ROOT as REPO
from probeless.paths import SHARED_DATA

TESTS = Path(__file__).resolve().parent
GRAPHS = TESTS / "graphs"

__all__ = ["GRAPHS", "REPO", "SHARED_DATA", "TESTS"]
