"""``probeless eval envmap``: the oracle mode is named in the table and the JSON; common-texel scores."""

from __future__ import annotations

import json

import numpy as np
import pytest

from probeless.envmap.evaluate import MethodResult
from probeless.envmap.methods import METRICS, TABLE
from probeless.envmap.score import SCORES
from probeless.eval import envmap as cli


def parse(argv):
    from probeless.cli import build_parser

    return build_parser().parse_args(["eval", "envmap", *argv])


def test_oracle_flag_is_the_default_mode_and_every_score_is_a_metric():
    assert parse(["s.yaml"]).oracle is False and parse(["s.yaml", "--oracle"]).oracle is True
    assert parse(["s.yaml"]).func is cli.run
    assert set(SCORES) <= set(METRICS) and set(TABLE) <= set(METRICS)


def test_table_names_its_mode():
    res = MethodResult("ours")
    res.add("sphere", {k: 1.0 for k in METRICS})
    text = cli.table({"ours": res}, "oracle")
    assert text.splitlines()[0].startswith("mode: oracle")
    assert all(k in text.splitlines()[1] for k in TABLE)


@pytest.mark.slow
@pytest.mark.gl
def test_oracle_json_on_a_short_run(capsys):
    ns = parse(["launch/scenes/convex_room.yaml", "--oracle", "--duration", "0.6", "--stride", "3", "--every", "2",
                "--face-size", "32", "--atlas-size", "256", "--methods", "ours", "baseline", "--json",
                "--no-progress"])
    assert ns.func(ns) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["mode"] == "oracle" and "true fisheye poses" in out["mode_detail"]
    for obj, ours in out["ours"].items():
        base = out["baseline"][obj]
        # the common texels are the same for both, and no more than either observed
        assert ours["common_coverage"] == pytest.approx(base["common_coverage"])
        assert ours["common_coverage"] <= min(ours["coverage"], base["coverage"]) + 1e-9
        assert set(SCORES) <= set(ours)
        assert np.isfinite(ours["psnr_common"]) and ours["psnr_common"] > base["psnr_common"]
