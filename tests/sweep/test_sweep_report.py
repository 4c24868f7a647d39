"""`probeless sweep report`: mean ± std over seeds per row and column label, a Markdown table and a bar plot."""

from __future__ import annotations

import statistics

import matplotlib.image
import pytest

from probeless.cli import main
from probeless.jsonio import dumps
from probeless.sweep.table import columns, write_table


@pytest.fixture
def results(tmp_path):
    axes, keys = ["method", "scene", "seed"], ["psnr"]
    (tmp_path / "sweep.json").write_text(dumps({"name": "t", "axes": axes, "collect": {"psnr": "x"},
                                                "report": {"rows": "method", "columns": "scene"}}))
    values = {("ours", "a"): [20.0, 21.0, 23.5], ("ours", "b"): [18.0, 18.5, None],
              ("baseline", "a"): [15.0, 15.25, 14.0], ("baseline", "b"): [None, None, None]}
    rows = []
    for (method, scene), vs in values.items():
        for seed, v in enumerate(vs):
            rows.append({"run_id": f"{method}-{scene}-{seed}", "status": "ok" if v is not None else "failed",
                         "method": method, "scene": f"launch/scenes/{scene}.yaml", "seed": str(seed), "psnr": v,
                         "error": None if v is not None else "exit status 1: boom"})
    write_table(rows, columns(axes, keys), tmp_path)
    return tmp_path, values


def test_report_aggregates_over_seeds_and_plots(results, capsys):
    out, values = results
    assert main(["sweep", "report", str(out)]) == 0
    text = capsys.readouterr().out
    assert "4 failed" in text and "ours-b-2: exit status 1: boom" in text
    table = {line.split("|")[1].strip(): [c.strip() for c in line.split("|")[2:-1]]
             for line in text.splitlines() if line.startswith("| ") and "method" not in line}
    for (method, scene), vs in values.items():
        got = table[method][["a", "b"].index(scene)]
        ok = [v for v in vs if v is not None]
        if not ok:
            assert got == "-"
        else:
            assert got == f"{statistics.mean(ok):.3f} ± {statistics.stdev(ok):.3f}"
    png = matplotlib.image.imread(out / "report" / "psnr.png")
    assert png.ndim == 3 and png.shape[0] > 100 and png.shape[1] > 100
    assert (out / "report" / "report.md").read_text() == text


def test_report_of_a_directory_that_is_not_a_sweep(tmp_path, capsys):
    assert main(["sweep", "report", str(tmp_path)]) == 2
    assert "not a sweep results directory" in capsys.readouterr().err
