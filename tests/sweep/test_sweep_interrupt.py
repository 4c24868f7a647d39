"""An interrupted sweep (Ctrl-C) keeps what finished, marks the rest pending, and --resume runs only the rest."""

from __future__ import annotations

import signal
import subprocess
import sys
import time

import pytest
from sweep_common import ROOT, SCENES, read_csv, write_sweep

from probeless.sweep.driver import run_sweep

pytestmark = [pytest.mark.slow, pytest.mark.gl, pytest.mark.graph]


def test_interrupted_sweep_resumes_where_it_stopped(tmp_path):
    # one scene x 2 methods: the first run finishes, the second is cut short (run one at a time)
    sweep, out = write_sweep(tmp_path / "small.yaml", scenes=SCENES[:1]), tmp_path / "results"
    total = 2
    proc = subprocess.Popen([sys.executable, "-m", "probeless", "sweep", str(sweep), "-o", str(out), "--jobs", "1",
                             "--no-progress"], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 90
    while not list(out.glob("*/run.json")) and time.monotonic() < deadline:  # the first run has finished
        time.sleep(0.2)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and "--resume" in err, err[-2000:]
    rows = read_csv(out / "results.csv")
    done = {r["run_id"] for r in rows if r["status"] == "ok"}
    assert 1 <= len(done) < total and len(rows) == total and {r["status"] for r in rows} <= {"ok", "pending"}, rows
    s = run_sweep(sweep, out, jobs=2, resume=True, show_progress=False)
    assert (s.skipped, s.ok, s.failed) == (len(done), total - len(done), 0)
    assert all(r["status"] == "ok" for r in read_csv(out / "results.csv"))
