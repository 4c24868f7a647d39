"""Synthetic HDR-expansion ground truth (probeless.hdr.synthetic) and ``probeless eval hdr-expand``.

On light_switch with the test's small settings (SMALL: 27480 points, 1796 over-exposed) the eval gives an
over-exposed cloud RMS of 0.936 for ``ldr`` and 0.646 for ``pmatch-rgb`` (cloud units), diffuse-sphere RMS
0.182 vs 0.112 (photo aimed at the over-exposed points, the default).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from locations import REPO

from probeless.cli import main
from probeless.hdr.expand import METHODS
from probeless.hdr.transfer import overexposed

SCENE = REPO / "launch" / "scenes" / "light_switch.yaml"
SMALL = ["--frames", "4", "--scale", "0.2", "--voxel", "0.03", "--views", "2", "--size", "96", "--face", "32",
         "--sphere", "48"]


@pytest.fixture(scope="module")
def case():
    from probeless.hdr.synthetic import synthetic_case

    return synthetic_case(SCENE, frames=4, scale=0.2, voxel=0.03, exposure=1.0)


@pytest.mark.gl
def test_synthetic_ldr_is_the_clipped_exposed_truth_with_overexposed_points(case):
    assert case.points.shape == case.true_radiance.shape == case.ldr_colors.shape
    assert case.points.dtype == case.true_radiance.dtype == case.ldr_colors.dtype == np.float32
    np.testing.assert_array_equal(case.ldr_colors, np.clip(np.float32(case.exposure) * case.true_radiance, 0, 1))
    assert case.true_radiance.max() > 1.0 and overexposed(case.ldr_colors).sum() > 100
    assert case.photo_hdr.dtype == np.float32 and case.photo_hdr.ndim == 3 and case.photo_hdr.max() > 0.37
    assert np.isfinite(case.true_radiance).all() and case.true_radiance.min() >= 0


@pytest.mark.gl
def test_synthetic_case_is_deterministic(case):
    from probeless.hdr.synthetic import synthetic_case

    again = synthetic_case(SCENE, frames=4, scale=0.2, voxel=0.03, exposure=1.0)
    np.testing.assert_array_equal(again.points, case.points)
    np.testing.assert_array_equal(again.true_radiance, case.true_radiance)
    np.testing.assert_array_equal(again.photo_hdr, case.photo_hdr)


@pytest.mark.gl
@pytest.mark.slow
def test_eval_json_has_every_method_and_pmatch_beats_ldr_on_overexposed(capsys):
    assert main(["eval", "hdr-expand", str(SCENE), *SMALL, "--json", "--no-progress"]) == 0
    out = capsys.readouterr().out
    res = json.loads(out)
    assert out.count("\n") == 1 and res["methods"] == ["ldr", *METHODS]
    (scene,) = res["scenes"]
    assert set(scene["methods"]) == {"ldr", *METHODS}
    for row in scene["methods"].values():
        for key in ("cloud_rms", "cloud_rms_overexposed", "diffuse_rms", "diffuse_ssim", "mirror_rms", "mirror_ssim"):
            assert np.isfinite(row[key]), key
    rows = scene["methods"]
    assert rows["pmatch-rgb"]["cloud_rms_overexposed"] < rows["ldr"]["cloud_rms_overexposed"]
    assert rows["pmatch-rgb"]["diffuse_rms"] < rows["ldr"]["diffuse_rms"]


def test_synthetic_case_rejects_an_unknown_photo_target():
    from probeless.errors import HdrError
    from probeless.hdr.synthetic import synthetic_case

    with pytest.raises(HdrError, match="photo_target"):
        synthetic_case(SCENE, photo_target="ceiling")


def test_eval_rejects_an_unknown_method(capsys):
    assert main(["eval", "hdr-expand", str(SCENE), "--methods", "ldr", "nope", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "unknown method 'nope'" in err and "pmatch-rgb" in err
