"""The README's own code runs as written: the quick start's commands and every block of "Writing a node".

The blocks are taken from README.md at test time, so an edit that breaks them fails here. A block whose first
line is a comment naming a file (``# blur.py``, ``# graph.yaml, ...``) is written to that file; ``sh`` blocks run
in bash with ``set -e``. References are OpenCV on the test pattern the graph's camera publishes.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from locations import REPO

from probeless.nodes.demo.pattern import pattern_image

README = REPO / "README.md"
VENV_BIN = Path(sys.executable).parent
_FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.S | re.M)


def section(title: str) -> str:
    """The README's section whose heading starts with ``title``, up to the next heading of its level or above."""
    out, level, fenced = None, 0, False
    for line in README.read_text().splitlines(keepends=True):
        if line.startswith("```"):
            fenced = not fenced
        heading = re.match(r"(#+) ", line) if not fenced else None
        if out is None:
            if heading and line[heading.end():].startswith(title):
                out, level = [], len(heading.group(1))
        elif heading and len(heading.group(1)) <= level:
            break
        else:
            out.append(line)
    assert out is not None, f"README.md has no section {title!r}"
    return "".join(out)


def blocks(text: str) -> list[tuple[str, str]]:
    return [(m.group(1), m.group(2)) for m in _FENCE.finditer(text)]


def file_name(code: str) -> str | None:
    """``blur.py`` of a block starting ``# blur.py`` (or ``# graph.yaml, in the same folder``)."""
    m = re.match(r"#\s*([\w./-]+\.(?:py|yaml|toml))\b", code)
    return m.group(1) if m else None


def run_sh(code: str, cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PATH=f"{VENV_BIN}{os.pathsep}{os.environ.get('PATH', '')}")
    script = "set -e\n" + "\n".join(line for line in code.splitlines() if not line.startswith("make "))
    return subprocess.run(["bash", "-c", script], cwd=cwd, env=env, capture_output=True, text=True, timeout=300,
                          stdin=subprocess.DEVNULL)


def _rgb(path: Path) -> np.ndarray:
    img = cv2.imread(str(path))
    assert img is not None, path
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


@pytest.mark.graph
@pytest.mark.slow
def test_writing_a_node_runs_as_written(tmp_path):
    found = blocks(section("Writing a node"))
    files = {file_name(code): code for lang, code in found if file_name(code)}
    assert {"blur.py", "graph.yaml", "test_blur.py"} <= set(files), sorted(files)
    folder = tmp_path / "my_work"   # a folder of the user's own, outside the repository
    folder.mkdir()
    for name, code in files.items():
        if not name.endswith(".toml"):
            (folder / name).write_text(code)
    for lang, code in found:
        if lang == "sh":
            run = run_sh(code, folder)
            assert run.returncode == 0, run.stdout + run.stderr
    # the graph ran the user's node: the summary's last frame is OpenCV's blur of the camera's last pattern
    import yaml

    graph = yaml.safe_load(files["graph.yaml"])
    nodes = {n["id"]: n for n in graph["nodes"]}
    cam, ksize = nodes["camera"]["params"], nodes["blur"]["params"]["ksize"]
    expected = cv2.GaussianBlur(pattern_image(cam["width"], cam["height"], cam["count"] - 1), (ksize, ksize), 0)
    out_dir = folder / nodes["summary"]["params"]["out_dir"]
    np.testing.assert_array_equal(_rgb(out_dir / "last_frame.png"), expected)
    # the README's unit test passes, and fails when the node is broken
    test = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "test_blur.py"],
                          cwd=folder, capture_output=True, text=True, timeout=300, stdin=subprocess.DEVNULL)
    assert test.returncode == 0, test.stdout + test.stderr
    (folder / "blur.py").write_text(files["blur.py"].replace("(ksize, ksize), 0)", "(ksize, ksize), 2)"))
    test = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "test_blur.py"],
                          cwd=folder, capture_output=True, text=True, timeout=300, stdin=subprocess.DEVNULL)
    assert test.returncode == 1, test.stdout


@pytest.mark.graph
@pytest.mark.slow
def test_quick_start_runs_as_written(tmp_path):
    """The quick start's commands from a copy of the repository's layout: its launch/ and .venv, a fresh out/."""
    (sh,) = [code for lang, code in blocks(section("Quick start")) if lang == "sh"]
    assert ".venv/bin/probeless" in sh and "../shared" not in sh
    (tmp_path / "launch").symlink_to(REPO / "launch")
    (tmp_path / ".venv").symlink_to(Path(sys.prefix))
    run = run_sh(sh, tmp_path)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "transform: recorded with operation='blur', graph has operation='edges': running image_transform live" \
        in run.stderr
    assert "from the recording: camera (pattern_source)" in run.stderr
    # the replay ran the edge detector live on the recorded camera frames (OpenCV Canny as in image_transform)
    last = pattern_image(640, 480, 59)
    edges = cv2.Canny(cv2.cvtColor(last, cv2.COLOR_RGB2GRAY), 50, 150)
    np.testing.assert_array_equal(_rgb(tmp_path / "out/quick/edges/last_frame.png"), np.repeat(edges[..., None], 3, 2))
    np.testing.assert_array_equal(_rgb(tmp_path / "out/quick/blur/last_frame.png"),
                                  cv2.GaussianBlur(last, (5, 5), 0))
