"""How a file was made: the package version and the repository revision, stored with recordings."""

from __future__ import annotations

import subprocess

from probeless.paths import REPO_ROOT


def git_revision() -> str:
    """The repository's HEAD revision (with '+dirty'), or 'unknown' outside a git checkout."""
    try:
        rev = subprocess.run(["git", "-C", str(REPO_ROOT), "rev-parse", "HEAD"], capture_output=True, text=True,
                             timeout=5).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(REPO_ROOT), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=5).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return (rev + ("+dirty" if dirty else "")) if rev else "unknown"
