"""`probeless sweep` on the local process pool: a small envmap sweep (2 scenes x 2 methods) is complete and
matches the evaluation run by hand, reproduces, resumes without rerunning, and reports a failing run while
the others finish."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from sweep_common import CHEAP, ROOT, SCENES, read_csv, values, write_sweep

from probeless.cli import main
from probeless.sweep.driver import run_sweep

pytestmark = [pytest.mark.gl, pytest.mark.graph]


@pytest.fixture(scope="module")
def swept(tmp_path_factory):
    d = tmp_path_factory.mktemp("sweep")
    sweep = write_sweep(d / "small.yaml")
    summary = run_sweep(sweep, d / "results", jobs=2, show_progress=False)
    return sweep, d / "results", summary


def test_results_are_complete_and_match_the_evaluation(swept):
    _, out, summary = swept
    assert (summary.total, summary.ok, summary.failed) == (4, 4, 0)
    rows = read_csv(out / "results.csv")
    assert {(r["scene"], r["method"]) for r in rows} == {(str(ROOT / s), m) for s in SCENES
                                                         for m in ("ours", "baseline")}
    assert all(r["status"] == "ok" and float(r["psnr"]) > 5 for r in rows)
    # one run against the evaluation run by hand, outside the sweep
    out_json = subprocess.run([sys.executable, "-m", "probeless", "eval", "envmap", str(ROOT / SCENES[0]), *CHEAP,
                               "--methods", "baseline", "--json", "--no-progress"], cwd=ROOT, capture_output=True,
                              text=True, check=True).stdout
    by_hand = json.loads(out_json)["baseline"]
    expected = sum(o["envmap_psnr"] for o in by_hand.values()) / len(by_hand)
    row = next(r for r in rows if r["scene"] == str(ROOT / SCENES[0]) and r["method"] == "baseline")
    assert float(row["psnr"]) == pytest.approx(expected, rel=1e-12)
    run_dir = out / row["run_id"]
    assert json.loads((run_dir / "result.json").read_text())["baseline"].keys() == by_hand.keys()
    assert json.loads((run_dir / "run.json").read_text())["status"] == "ok"


def test_parquet_table_matches_the_csv(swept):
    pq = pytest.importorskip("pyarrow.parquet")
    _, out, _ = swept
    rows = read_csv(out / "results.csv")
    table = pq.read_table(out / "results.parquet")
    assert table.column("psnr").to_pylist() == [float(r["psnr"]) for r in rows]
    assert table.column("method").to_pylist() == [r["method"] for r in rows]


def test_sweep_is_reproducible(swept, tmp_path):
    sweep, out, _ = swept
    # one scene's two runs again (a run per CPU; the other scene's runs are the same code path)
    run_sweep(sweep, tmp_path / "again", jobs=2, only=["scene=red_wall"], show_progress=False)
    again = values(read_csv(tmp_path / "again" / "results.csv"))
    assert len(again) == 2 and again == {k: v for k, v in values(read_csv(out / "results.csv")).items() if k in again}


def test_resume_reruns_nothing_then_only_what_is_unfinished(swept):
    sweep, out, _ = swept
    before = {p.parent.name: p.stat().st_mtime_ns for p in out.glob("*/run.json")}
    s = run_sweep(sweep, out, jobs=2, resume=True, show_progress=False)
    assert (s.skipped, s.ok, s.failed) == (4, 0, 0)
    assert {p.parent.name: p.stat().st_mtime_ns for p in out.glob("*/run.json")} == before
    # an interrupted sweep: one run never finished (no run.json)
    victim = sorted(before)[0]
    (out / victim / "run.json").unlink()
    s = run_sweep(sweep, out, jobs=2, resume=True, show_progress=False)
    assert (s.skipped, s.ok) == (3, 1)
    after = {p.parent.name: p.stat().st_mtime_ns for p in out.glob("*/run.json")}
    assert [k for k in after if after[k] != before.get(k)] == [victim]


def test_a_failing_run_is_reported_and_the_sweep_goes_on(tmp_path, capsys):
    bad = tmp_path / "broken_scene.yaml"  # exists (passes the up-front check), fails when the run reads it
    bad.write_text("name: broken\nnonsense_key: 1\n")
    sweep = write_sweep(tmp_path / "fail.yaml", scenes=(SCENES[0], str(bad)), methods=("ours",))
    rc = main(["sweep", str(sweep), "-o", str(tmp_path / "out"), "--jobs", "2", "--no-progress"])
    assert rc == 1
    rows = {r["run_id"]: r for r in read_csv(tmp_path / "out" / "results.csv")}
    assert rows["red_wall-ours"]["status"] == "ok" and float(rows["red_wall-ours"]["psnr"]) > 5
    failed = rows["broken_scene-ours"]
    assert failed["status"] == "failed" and failed["psnr"] == ""
    assert "nonsense_key" in failed["error"] and "exit status 2" in failed["error"]
    assert "failed: broken_scene-ours" in capsys.readouterr().out
    assert "nonsense_key" in (tmp_path / "out" / "broken_scene-ours" / "stderr.log").read_text()
