"""BRDFs of the PBGI renderer (probeless.pbgi.brdf and shaders/brdf.glsl) against Mitsuba 3, quadrature and
hand-computed values; the GLSL copy against the numpy one."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate

from probeless.errors import PbgiError
from probeless.pbgi import brdf

UP = np.array([0.0, 0.0, 1.0])
ROUGHNESS = (0.1, 0.3, 0.6, 1.0)


def random_dirs(rng, count: int, min_cos: float = 0.05) -> np.ndarray:
    """Unit vectors in the upper hemisphere (z >= min_cos), uniform in solid angle."""
    z = rng.uniform(min_cos, 1.0, count)
    phi = rng.uniform(0, 2 * np.pi, count)
    s = np.sqrt(1 - z * z)
    return np.stack([s * np.cos(phi), s * np.sin(phi), z], axis=-1)


def sphere_dir(theta: float, phi: float = 0.0) -> np.ndarray:
    return np.array([math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta)])


def hemisphere_grid(count: int, full_sphere: bool = False):
    """Midpoint quadrature on (theta, phi): directions (count, 2 count, 3) and solid-angle weights."""
    top = np.pi if full_sphere else np.pi / 2
    theta = (np.arange(count) + 0.5) * top / count
    phi = (np.arange(2 * count) + 0.5) * np.pi / count
    t, p = np.meshgrid(theta, phi, indexing="ij")
    d = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1)
    return d, np.sin(t) * (top / count) * (np.pi / count)


# --- Mitsuba 3 as the independent reference ---------------------------------------------------------------------


@pytest.fixture(scope="module")
def mi():
    mitsuba = pytest.importorskip("mitsuba")
    mitsuba.set_variant("scalar_rgb")
    return mitsuba


def mitsuba_f(mi, bsdf, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """Mitsuba's BRDF value f (its eval returns f cos(theta_o) in the local frame)."""
    si = mi.SurfaceInteraction3f()
    si.wi = mi.Vector3f(*wi)
    return np.array(bsdf.eval(mi.BSDFContext(), si, mi.Vector3f(*wo))) / wo[2]


@pytest.mark.parametrize("roughness", ROUGHNESS)
def test_ggx_with_unit_f0_equals_mitsubas_rough_conductor(mi, roughness):
    bsdf = mi.load_dict({"type": "roughconductor", "distribution": "ggx", "alpha": roughness ** 2,
                         "material": "none"})  # eta 0, k 1: Fresnel 1
    rng = np.random.default_rng(int(roughness * 10))
    wi, wo = random_dirs(rng, 40), random_dirs(rng, 40)
    ref = np.array([mitsuba_f(mi, bsdf, a, b) for a, b in zip(wi, wo)])
    got = brdf.ggx(np.ones(3), roughness, UP, wi, wo)
    np.testing.assert_allclose(got, ref, rtol=1e-4)


def test_ggx_is_rotation_invariant_and_matches_mitsuba_about_any_normal(mi):
    rng = np.random.default_rng(7)
    wi, wo = random_dirs(rng, 30), random_dirs(rng, 30)
    n = random_dirs(rng, 30, min_cos=-1.0)
    frames = brdf.tangent_frame(n)
    to_world = lambda v: np.einsum("nij,nj->ni", frames, v)  # noqa: E731
    bsdf = mi.load_dict({"type": "roughconductor", "distribution": "ggx", "alpha": 0.25, "material": "none"})
    ref = np.array([mitsuba_f(mi, bsdf, a, b) for a, b in zip(wi, wo)])
    np.testing.assert_allclose(brdf.ggx(np.ones(3), 0.5, n, to_world(wi), to_world(wo)), ref, rtol=1e-4)


def test_lambert_equals_mitsubas_diffuse(mi):
    base = [0.2, 0.5, 0.7]
    bsdf = mi.load_dict({"type": "diffuse", "reflectance": {"type": "rgb", "value": base}})
    rng = np.random.default_rng(3)
    wi, wo = random_dirs(rng, 20), random_dirs(rng, 20)
    ref = np.array([mitsuba_f(mi, bsdf, a, b) for a, b in zip(wi, wo)])
    np.testing.assert_allclose(brdf.lambert(base, UP, wi, wo), ref, rtol=1e-5)


def test_every_model_is_zero_below_either_horizon():
    above, below = sphere_dir(0.5), sphere_dir(2.0)
    for model in brdf.MODELS:
        for wi, wo in ((above, below), (below, above), (below, below)):
            assert np.all(brdf.evaluate(model, [0.8, 0.5, 0.3], 0.4, 0.5, UP, wi, wo) == 0.0)
        assert np.all(brdf.evaluate(model, [0.8, 0.5, 0.3], 0.4, 0.5, UP, above, sphere_dir(0.3, 1.0)) > 0)


# --- normalisation ----------------------------------------------------------------------------------------------


@pytest.mark.parametrize("roughness", (0.05, 0.3, 0.7, 1.0))
def test_ggx_distribution_projected_area_integrates_to_one(roughness):
    alpha = roughness ** 2
    density = lambda t: 2 * np.pi * brdf.ggx_d(alpha, UP, sphere_dir(t)) * math.cos(t) * math.sin(t)  # noqa: E731
    total, _ = integrate.quad(density, 0, np.pi / 2, points=[min(5 * alpha, 1.0)], limit=200)
    assert total == pytest.approx(1.0, abs=1e-6)


def test_lambert_albedo_is_the_base_colour():
    d, w = hemisphere_grid(200)
    f = brdf.lambert([0.2, 0.5, 0.9], UP, d, np.broadcast_to(sphere_dir(0.7), d.shape))
    np.testing.assert_allclose(np.einsum("ijc,ij->c", f * d[..., 2:], w), [0.2, 0.5, 0.9], rtol=1e-4)


@pytest.mark.parametrize("theta_o", (0.0, 1.0))
def test_ggx_white_furnace_albedo_is_at_most_one_and_near_one_when_smooth(theta_o):
    wo = sphere_dir(theta_o)
    albedo = {}
    for roughness in (0.2, 0.5, 1.0):
        d, w = hemisphere_grid(900 if roughness == 0.2 else 300)
        f = brdf.ggx(np.ones(3), roughness, UP, d, np.broadcast_to(wo, d.shape))[..., 0]
        albedo[roughness] = float(np.sum(f * d[..., 2] * w))
    assert all(a <= 1.0 for a in albedo.values())
    # single-scattering Smith loses energy as roughness grows (Mitsuba's roughconductor: 0.31 at alpha 1, normal)
    assert albedo[0.2] > 0.98 and albedo[0.2] > albedo[0.5] > albedo[1.0] > 0.25


# --- sampling ---------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("roughness", (0.2, 0.6))
def test_sampled_half_vectors_follow_d_cos(roughness):
    alpha = roughness ** 2
    rng = np.random.default_rng(11)
    h = brdf.sample_ggx_half(rng.random(200_000), rng.random(200_000), alpha)
    np.testing.assert_allclose(np.linalg.norm(h, axis=-1), 1.0, atol=1e-12)
    edges = np.linspace(0, np.arccos(0.0), 21) if roughness > 0.5 else np.linspace(0, 1.2, 21)
    counts, _ = np.histogram(np.arccos(np.clip(h[:, 2], -1, 1)), bins=edges)
    density = lambda t: 2 * np.pi * brdf.ggx_d(alpha, UP, sphere_dir(t)) * math.cos(t) * math.sin(t)  # noqa: E731
    expected = np.array([integrate.quad(density, a, b)[0] for a, b in zip(edges[:-1], edges[1:])]) * len(h)
    assert np.all(np.abs(counts - expected) < 5 * np.sqrt(expected) + 5)
    quadrants = np.histogram(np.arctan2(h[:, 1], h[:, 0]), bins=4, range=(-np.pi, np.pi))[0]
    np.testing.assert_allclose(quadrants / len(h), 0.25, atol=0.005)  # isotropic in phi


@pytest.mark.parametrize("theta_o", (0.0, np.radians(60)))
@pytest.mark.parametrize("roughness", (0.3, 0.8))
def test_reflected_pdf_integrates_to_the_fraction_of_half_vectors_facing_wo(theta_o, roughness):
    """Over the sphere of wi the pdf sums to P(wo.h > 0) (1 at normal incidence): a half-vector facing away
    from wo reflects into a direction no visible microfacet produces, which a renderer discards."""
    alpha, wo = roughness ** 2, sphere_dir(theta_o)
    h, wh = hemisphere_grid(600)
    facing = float(np.sum(np.where(h @ wo > 0, brdf.ggx_d(alpha, UP, h) * h[..., 2], 0.0) * wh))
    d, w = hemisphere_grid(600, full_sphere=True)
    pdf = brdf.pdf_ggx_reflect(alpha, UP, d, np.broadcast_to(wo, d.shape))
    assert float(np.sum(pdf * w)) == pytest.approx(facing, abs=2e-3)
    if theta_o == 0.0:
        assert facing == pytest.approx(1.0, abs=1e-3)
    else:
        assert facing < 0.999 if roughness == 0.3 else facing < 0.9
    upper = float(np.sum(np.where(d[..., 2] > 0, pdf, 0.0) * w))
    assert upper <= facing + 1e-3


@pytest.mark.parametrize("model,roughness", (("ggx", 0.3), ("disney", 0.5), ("ggx", 0.8)))
def test_importance_sampled_estimate_matches_quadrature(model, roughness):
    base, wo = np.array([0.9, 0.6, 0.3]), sphere_dir(np.radians(40), 0.3)
    d, w = hemisphere_grid(600)
    ref = np.einsum("ijc,ij->c", brdf.evaluate(model, base, roughness, 0.2, UP, d, np.broadcast_to(wo, d.shape))
                    * d[..., 2:], w)
    u = brdf.hammersley(np.arange(1 << 16), 1 << 16)
    h = brdf.sample_ggx_half(u[:, 0], u[:, 1], roughness ** 2)
    wi = brdf.reflect(np.broadcast_to(wo, h.shape), h)
    pdf = brdf.pdf_ggx_reflect(roughness ** 2, UP, wi, np.broadcast_to(wo, h.shape))
    f = brdf.evaluate(model, base, roughness, 0.2, UP, wi, np.broadcast_to(wo, h.shape))
    ok = pdf > 0  # pdf 0 (h facing away from wo): f is 0 there too, the sample is discarded
    assert np.all(f[~ok] == 0)
    estimate = np.sum(f[ok] * np.maximum(wi[ok, 2:], 0) / pdf[ok, None], axis=0) / len(h)
    np.testing.assert_allclose(estimate, ref, rtol=0.1 if model == "disney" else 0.01)  # disney: diffuse under GGX


def test_hammersley_points_are_the_base_2_radical_inverse():
    p = brdf.hammersley(np.arange(8), 8)
    np.testing.assert_array_equal(p[:, 0], np.arange(8) / 8)
    np.testing.assert_array_equal(p[:, 1], [0, 0.5, 0.25, 0.75, 0.125, 0.625, 0.375, 0.875])
    assert brdf.hammersley(np.array([0xFFFFFFFF]), 1)[0, 1] == 1 - 2.0 ** -32


def test_tangent_frames_are_orthonormal_and_right_handed():
    rng = np.random.default_rng(5)
    n = random_dirs(rng, 100, min_cos=-1.0)
    n = np.vstack([n, [[0, 0, 1.0], [0, 0, -1.0], [1.0, 0, 0]]])
    f = brdf.tangent_frame(n)
    np.testing.assert_allclose(np.einsum("nki,nkj->nij", f, f), np.broadcast_to(np.eye(3), f.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(f), 1.0, atol=1e-12)
    np.testing.assert_array_equal(f[..., 2], n)


# --- Disney -----------------------------------------------------------------------------------------------------


def test_disney_at_full_metalness_is_ggx_of_the_base_colour():
    rng = np.random.default_rng(2)
    wi, wo, base = random_dirs(rng, 50), random_dirs(rng, 50), rng.random((50, 3))
    r = rng.uniform(0.05, 1.0, 50)
    np.testing.assert_allclose(brdf.disney(base, r, 1.0, UP, wi, wo), brdf.ggx(base, r, UP, wi, wo), rtol=1e-12)


def test_disney_diffuse_is_lambert_where_fd90_is_one():
    rng = np.random.default_rng(4)
    wi, wo, base, metal = random_dirs(rng, 50), random_dirs(rng, 50), rng.random((50, 3)), rng.random(50)
    h = (wi + wo) / np.linalg.norm(wi + wo, axis=-1, keepdims=True)
    r = 0.25 / np.sum(wi * h, axis=-1) ** 2  # 0.5 + 2 r cos_d² = 1
    diffuse = brdf.disney(base, r, metal, UP, wi, wo) - brdf.ggx(brdf.disney_f0(base, metal), r, UP, wi, wo)
    np.testing.assert_allclose(diffuse, brdf.lambert(base, UP, wi, wo) * (1 - metal[:, None]), rtol=1e-10)


def test_disney_hand_computed_value():
    # wi 60 deg off the normal, wo along it: h 30 deg off, cos_d = cos 30; base 0.5, roughness 0.5, metalness 0.
    fd90 = 0.5 + 2 * 0.5 * 0.75                                  # 1.25
    diffuse = 0.5 / math.pi * (1 + (fd90 - 1) * 0.5 ** 5) * 1.0  # fl (cos_l 0.5) * fv (cos_v 1)
    a2 = 0.25 ** 2
    d = a2 / (math.pi * (0.75 * (a2 - 1) + 1) ** 2)
    g = 2 / (1 + math.sqrt(1 + a2 * 3.0)) * 1.0                  # tan² 60 = 3; G1(wo) = 1
    f = 0.04 + 0.96 * (1 - math.sqrt(3) / 2) ** 5
    expected = diffuse + d * g * f / (4 * 0.5 * 1.0)
    assert expected == pytest.approx(0.1647235, abs=1e-7)
    got = brdf.disney([0.5, 0.5, 0.5], 0.5, 0.0, UP, sphere_dir(np.radians(60)), UP)
    np.testing.assert_allclose(got, expected, rtol=1e-12)


def test_ggx_hand_computed_value_with_fresnel_at_the_half_vector():
    # wi, wo mirror images 60 deg off the normal: h = n, D = 1 / (pi alpha²) = 5.09296, G1 = 0.957072 each,
    # F = f0 + (1 - f0) / 32 (wo.h = 0.5, not n.h = 1): 0.07, 0.515625, 1; f = D G1² F / (4 cos_i cos_o = 1).
    a2 = 0.25 ** 2                                  # roughness 0.5
    d = 1 / (math.pi * a2)
    g1 = 2 / (1 + math.sqrt(1 + a2 * 3.0))         # tan² 60 = 3
    f0 = np.array([0.04, 0.5, 1.0])
    f = f0 + (1 - f0) * 0.5 ** 5
    expected = d * g1 * g1 * f / (4 * 0.5 * 0.5)
    np.testing.assert_allclose(expected, [0.3265502, 2.4053922, 4.6650031], rtol=1e-7)
    got = brdf.ggx(f0, 0.5, UP, sphere_dir(np.radians(60)), sphere_dir(np.radians(60), np.pi))
    np.testing.assert_allclose(got, expected, rtol=1e-12)


def test_evaluate_dispatches_and_rejects_unknown_models():
    wi, wo, base = sphere_dir(0.4), sphere_dir(0.8, 2.0), [0.3, 0.6, 0.9]
    np.testing.assert_array_equal(brdf.evaluate("lambert", base, 0.3, 0.7, UP, wi, wo), brdf.lambert(base, UP, wi, wo))
    np.testing.assert_array_equal(brdf.evaluate("ggx", base, 0.3, 0.7, UP, wi, wo), brdf.ggx(base, 0.3, UP, wi, wo))
    np.testing.assert_array_equal(brdf.evaluate("disney", base, 0.3, 0.7, UP, wi, wo),
                                  brdf.disney(base, 0.3, 0.7, UP, wi, wo))
    with pytest.raises(PbgiError, match="phong"):
        brdf.evaluate("phong", base, 0.3, 0.7, UP, wi, wo)


# --- GLSL == numpy ----------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def glsl_probe():
    """Run shaders/brdf_probe.comp.glsl on 512 random records: (inputs dict, outputs (N, 20) float32)."""
    from probeless.gl.context import create_context
    from probeless.gl.programs import load_program

    rng = np.random.default_rng(1)
    count = 512
    n = random_dirs(rng, count, min_cos=-1.0)
    frames = brdf.tangent_frame(n)
    wi = np.einsum("nij,nj->ni", frames, random_dirs(rng, count, min_cos=0.05))
    wo = np.einsum("nij,nj->ni", frames, random_dirs(rng, count, min_cos=0.05))
    wi[:16] = np.einsum("nij,nj->ni", frames[:16], random_dirs(rng, 16) * [1, 1, -1])  # below
    inp = dict(n=n, wi=wi, wo=wo, base=rng.random((count, 3)), roughness=rng.uniform(0.05, 1.0, count),
               metalness=rng.random(count), model=np.arange(count) % 3, u=rng.random((count, 2)),
               alpha=rng.uniform(0.01, 1.0, count))
    record = np.hstack([inp["n"], inp["wi"], inp["wo"], inp["base"], inp["roughness"][:, None],
                        inp["metalness"][:, None], inp["model"][:, None], inp["u"], inp["alpha"][:, None],
                        np.zeros((count, 2))]).astype(np.float32)
    inp = {k: v.astype(np.float32).astype(np.float64) for k, v in inp.items()}  # what the GPU saw
    ctx = create_context()
    prog = load_program(ctx, "brdf_probe", shader_dir=brdf.SHADER_DIR)
    src, dst = ctx.buffer(record.tobytes()), ctx.buffer(reserve=record.nbytes)
    src.bind_to_storage_buffer(0)
    dst.bind_to_storage_buffer(1)
    prog["count"] = count
    prog.run((count + 63) // 64)
    out = np.frombuffer(dst.read(), np.float32).reshape(count, 20).astype(np.float64)
    ctx.release()
    return inp, out


@pytest.mark.gl
def test_glsl_brdf_eval_equals_numpy(glsl_probe):
    inp, out = glsl_probe
    models = np.array(brdf.MODELS)[inp["model"].astype(int)]
    ref = np.array([brdf.evaluate(m, inp["base"][i], inp["roughness"][i], inp["metalness"][i], inp["n"][i],
                                  inp["wi"][i], inp["wo"][i]) for i, m in enumerate(models)])
    assert np.all(ref[:16] == 0) and np.all(ref[16:] > 0)
    np.testing.assert_allclose(out[:, :3], ref, rtol=1e-3, atol=1e-6)


@pytest.mark.gl
def test_glsl_sampling_pdf_hammersley_and_frame_equal_numpy(glsl_probe):
    inp, out = glsl_probe
    pdf = brdf.pdf_ggx_reflect(inp["alpha"], inp["n"], inp["wi"], inp["wo"])
    np.testing.assert_allclose(out[:, 3], pdf, rtol=1e-3, atol=1e-6)
    h = brdf.sample_ggx_half(inp["u"][:, 0], inp["u"][:, 1], inp["alpha"])
    np.testing.assert_allclose(out[:, 4:7], h, rtol=1e-3, atol=2e-6)
    np.testing.assert_allclose(out[:, 7:9], brdf.hammersley(np.arange(len(out)), len(out)), rtol=1e-6)
    frames = brdf.tangent_frame(inp["n"])
    np.testing.assert_allclose(out[:, 9:18].reshape(-1, 3, 3), frames.transpose(0, 2, 1), atol=2e-5)
