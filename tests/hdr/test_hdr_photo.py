"""``probeless hdr photo``: the synthetic scene's HDR photo as a file, and the committed photo of
launch/hdr_slam.yaml kept in step with the renderer."""

from __future__ import annotations

import subprocess
import sys

import cv2
import numpy as np
import pytest
from locations import REPO

from probeless.hdr.synthetic import synthetic_case

LOUNGE = REPO / "launch/scenes/l_shaped_lounge.yaml"
CONVEX = REPO / "launch/scenes/convex_room.yaml"
COMMITTED = REPO / "launch/scenes/photos/convex_room.hdr"


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "probeless", "hdr", "photo", *map(str, args)],
                          capture_output=True, text=True, cwd=REPO)


@pytest.mark.slow
@pytest.mark.gl
def test_photo_file_is_the_synthetic_case_photo_and_the_committed_one(tmp_path):
    out = tmp_path / "convex.hdr"
    r = _cli(CONVEX, "-o", out, "--target", "look-at")
    assert r.returncode == 0, r.stderr
    written = cv2.imread(str(out), cv2.IMREAD_ANYDEPTH | cv2.IMREAD_COLOR)[..., ::-1]
    photo = synthetic_case(CONVEX, photo_target="look-at").photo_hdr
    assert written.shape == photo.shape == (240, 320, 3)
    # Radiance RGBE keeps 8 mantissa bits of the largest channel: error <= 2^-7 of that channel
    bound = photo.max(axis=-1, keepdims=True) * 2.0 ** -7 + 1e-30
    assert np.all(np.abs(written - photo) <= bound)
    assert out.read_bytes() == COMMITTED.read_bytes(), "regenerate launch/scenes/photos (ASSETS.md)"


def test_photo_bad_arguments(tmp_path):
    r = _cli(LOUNGE, "-o", tmp_path / "photo.png")
    assert r.returncode == 2 and "photo.png" in r.stderr
    r = _cli(tmp_path / "none.yaml", "-o", tmp_path / "p.hdr")
    assert r.returncode == 2 and "none.yaml" in r.stderr
    r = _cli(LOUNGE, "-o", tmp_path / "missing" / "p.hdr")
    assert r.returncode == 2 and "missing" in r.stderr
    r = _cli(LOUNGE, "-o", tmp_path / "p.hdr", "--size", "0", "10")
    assert r.returncode == 2 and "--size" in r.stderr
