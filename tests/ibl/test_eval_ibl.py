"""``probeless eval ibl``'s Mitsuba side: the envmap convention it relies on, and a small sphere against Mitsuba 3."""

from __future__ import annotations

import numpy as np
import pytest

mi = pytest.importorskip("mitsuba")


def test_mitsuba_envmap_pixel_directions_match_its_emitter():
    """Every pixel of a bitmap is what Mitsuba's envmap emitter returns along the direction we give that pixel."""
    from probeless.eval.ibl_mitsuba import mitsuba_envmap_directions
    from probeless.pbgi.reference import _mitsuba

    m = _mitsuba()
    rows, cols = 12, 24
    img = np.random.default_rng(3).uniform(0.1, 1.0, (rows, cols, 3)).astype(np.float32)
    emitter = m.load_dict({"type": "envmap", "bitmap": m.Bitmap(img)})
    d = mitsuba_envmap_directions(rows, cols)
    for r in range(1, rows - 1):  # the first and last rows sit on the poles, where every column meets
        for c in (0, 5, 11, cols - 1):
            si = m.SurfaceInteraction3f()
            si.wi = m.Vector3f(*(-d[r, c]))
            np.testing.assert_allclose(np.array(emitter.eval(si)), img[r, c], rtol=1e-4)


@pytest.mark.slow
@pytest.mark.gl
def test_small_sphere_under_an_hdr_panorama_agrees_with_mitsuba():
    """Diffuse and a rough white metal through the compositor's message path vs Mitsuba (the eval's functions, a
    64-px image): within 6 % RMS once the reference's own noise is taken out (the old shader: 7.7x for GGX 0.6)."""
    from probeless.eval.ibl import HDRI, load_maps
    from probeless.eval.ibl_mitsuba import (
        camera,
        cases,
        compare,
        reference_noise,
        render_mitsuba,
        render_ours,
        sphere_mask,
    )
    from probeless.gl.context import create_context

    path = HDRI / "studio_small_03_1k.hdr"
    if not path.is_file():
        pytest.skip(f"no panorama at {path}")

    class Ns:
        hdri, room, face = [str(path)], "", 64

    (faces, lookup), = load_maps(Ns).values()
    size = 48
    K, pose = camera(size)
    mask = sphere_mask(K, pose, size)
    ctx = create_context()
    for case in [c for c in cases([0.6]) if c.name in ("diffuse", "ggx 0.6")]:
        refs = [render_mitsuba(lookup, case, K, pose, size, 96, seed) for seed in (0, 1)]
        ref = 0.5 * (refs[0] + refs[1])
        ours = render_ours(faces, case, K, pose, size, ctx, compensated=False)
        got = compare(ours, ref, mask)
        corrected = np.sqrt(max(got["rel_rms"] ** 2 - reference_noise(*refs, mask) ** 2, 0.0))
        assert corrected < 0.06, (case.name, got)
        assert got["mean_ratio"] == pytest.approx(1.0, abs=0.04), (case.name, got)
    ctx.release()
