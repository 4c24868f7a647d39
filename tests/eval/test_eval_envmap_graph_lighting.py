"""Issue 29: ``probeless eval envmap --graph ... --graph-lighting ldr hdr`` runs each method once per lighting mode
and scores every run on the texels all runs observed, so LDR and linear HDR maps compare in one table. The graph
runs themselves are stood in for (their command lines are checked, their maps are written here)."""

from __future__ import annotations

import numpy as np
import pytest

from probeless.color import linear_to_srgb
from probeless.envmap.score import score_envmap
from probeless.errors import ProbelessError
from probeless.eval import envmap_graph as eg

S, STAMP, EXPOSURE = 16, 5_000, 0.5


def _truth() -> eg.Truth:
    rng = np.random.default_rng(11)
    hdr = rng.uniform(0.1, 1.0, (6, S, S, 3)).astype(np.float32)
    hdr[2, 4:8, 4:8] = 20.0  # a lamp the LDR camera clips
    t = eg.Truth()
    t.hdr["o", STAMP], t.exposure[STAMP] = hdr, np.full(3, EXPOSURE)
    t.ldr["o", STAMP] = linear_to_srgb(np.clip(hdr * EXPOSURE, 0, 1)).astype(np.float32)
    return t


@pytest.fixture
def fake_graph(monkeypatch, tmp_path):
    """Stand-ins for the launch (records the command line) and the recorded maps: the LDR run observes every texel,
    the HDR run only faces 0-2 (and has the lamp unclipped)."""
    truth, calls = _truth(), []
    half = np.zeros((6, S, S), bool)
    half[:3] = True
    maps = {"ldr": (np.clip(truth.ldr["o", STAMP] + 0.01, 0, 1), np.ones((6, S, S), bool), False),
            "hdr": (truth.hdr["o", STAMP] * EXPOSURE * 1.01, half, True)}

    def read_maps(path):
        faces, observed, linear = maps[path.parent.name.split("_")[-1]]
        return {("o", STAMP): (faces, observed)}, linear

    monkeypatch.setattr(eg, "_run", lambda cmd, log, show: calls.append(cmd))
    monkeypatch.setattr(eg, "read_maps", read_maps)
    monkeypatch.setattr(eg, "read_truth", lambda recording: truth)
    monkeypatch.setattr("probeless.eval.envmap.scene_path", lambda source: "scene.yaml")
    return truth, calls, half, tmp_path, {k: v[0] for k, v in maps.items()}


def test_each_lighting_mode_is_one_run_scored_on_the_texels_all_runs_observed(fake_graph):
    truth, calls, half, tmp_path, fake_graph_maps = fake_graph
    result = eg.evaluate_graph(str(tmp_path / "rec.mcap"), graph="launch/probeless.yaml", methods=["ours"],
                               duration=None, envmap_size=S, out_dir=tmp_path / "runs",
                               graph_args=["photo:=room.hdr"], show_progress=False, lightings=["ldr", "hdr"])
    assert [c[c.index("photo:=room.hdr") + 1] for c in calls] == ["lighting:=ldr", "lighting:=hdr"]
    assert all("envmap_node:=cubemap_renderer" in c for c in calls)
    assert result["linear_maps"] == {"ours[ldr]": False, "ours[hdr]": True}
    ldr, hdr = result["methods"]["ours[ldr]"]["o"], result["methods"]["ours[hdr]"]["o"]
    # both on faces 0-2 (what the HDR run observed): the scores an independent call gives on that common set
    for name, linear, got in (("ldr", False, ldr), ("hdr", True, hdr)):
        est = fake_graph_maps[name]
        want = score_envmap(est, truth.ldr["o", STAMP], truth.hdr["o", STAMP], exposure=np.full(3, EXPOSURE),
                            observed=np.ones((6, S, S), bool) if not linear else half, common=half, linear=linear)
        for k in ("psnr_common", "log_rmse_hdr", "pu21_psnr", "common_coverage"):
            assert got[k] == pytest.approx(want[k], rel=1e-6, nan_ok=True), k
    assert ldr["common_coverage"] == pytest.approx(0.5, abs=1e-6) == hdr["common_coverage"]
    assert hdr["log_rmse_hdr"] < 0.01 < ldr["log_rmse_hdr"]  # the lamp clips in the LDR map only


def test_lighting_given_twice_is_an_error(fake_graph):
    tmp_path = fake_graph[3]
    for lightings, args in ((["ldr", "ldr"], []), (["ldr", "hdr"], ["lighting:=hdr"])):
        with pytest.raises(ProbelessError, match="lighting"):
            eg.evaluate_graph(str(tmp_path / "rec.mcap"), graph="launch/probeless.yaml", methods=["ours"],
                              duration=None, envmap_size=S, out_dir=tmp_path, graph_args=args, show_progress=False,
                              lightings=lightings)
