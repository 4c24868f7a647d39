"""HDR lighting in the live pipeline: the hdr_atlas_expander node, the cubemap renderer's HDR path and
``launch/probeless.yaml lighting:=hdr`` (launch/lighting/hdr.yaml)."""

from __future__ import annotations

import dataclasses
import io

import numpy as np
import pytest
from locations import REPO

from probeless.coarse.model import CoarseConfig, make_layout
from probeless.coarse.texels import texel_map
from probeless.color import srgb_to_linear
from probeless.envmap.cubemap import EnvmapRenderer, prefilter
from probeless.envmap.sh import project_cubemap
from probeless.hdr.coarse import dense_linear, expand_atlas
from probeless.messages.geometry import Floorplan
from probeless.messages.header import Header
from probeless.messages.lighting import BrightnessDelta, Cubemap, SHCoefficients
from probeless.messages.mesh import HdrPointCloud, PointCloud
from probeless.messages.sensor import Image
from probeless.nodes.envmap.cubemap import CubemapRenderer
from probeless.nodes.hdr.atlas_expander import HdrAtlasExpander
from probeless.runtime.params import load_params
from probeless.runtime.testing import RecordingContext, run_node

FLOORPLAN = np.array([[0, 0], [5, 0], [5, 4], [0, 4]], float)  # convex_room: wall 1 is x = 5
CEILING = 2.6
PAD = 2  # layout_atlas's padding ring


def _floorplan() -> Floorplan:
    return Floorplan(Header(0, "world"), FLOORPLAN, CEILING)


def _photo(encoding: str = "rgbf32") -> Image:
    data = np.random.default_rng(1).random((16, 32, 3)) * 4
    data[2:4, 5:8] = 400.0  # a lamp: the operators' peak comes from the photo's brightest pixel (issue 27)
    data = data.astype(np.float16 if encoding == "rgbf16" else np.float32)
    return Image(Header(1, "pano"), data, encoding)


# ---------------------------------------------------------------- hdr_atlas_expander

ATLAS = 64
EXP_PARAMS = {"atlas_size": ATLAS, "method": "landis-pc", "min_period_s": 0.0}


def _ldr_atlas(stamp: int = 5, seed: int = 3, observed: float = 0.7) -> Image:
    """rgba8 atlas of the convex room at 64 texels: random colours, ``observed`` of it seen, some saturated."""
    rng = np.random.default_rng(seed)
    a = rng.integers(20, 200, (ATLAS, ATLAS, 4)).astype(np.uint8)
    a[..., 3] = np.where(rng.random((ATLAS, ATLAS)) < observed, 255, 0)
    a[rng.random((ATLAS, ATLAS)) < 0.05, :3] = 255
    return Image(Header(stamp, "world"), a, "rgba8")


def _texmap():
    return texel_map(make_layout(FLOORPLAN, CEILING, CoarseConfig(ATLAS)))


def test_atlas_expander_publishes_expand_atlas_as_an_rgbf32_atlas():
    atlas, photo = _ldr_atlas(), _photo("rgbf16")
    ctx = run_node(HdrAtlasExpander, [("floorplan", _floorplan()), ("atlas", atlas), ("photo", photo)], EXP_PARAMS)
    (out,) = ctx.outputs("atlas")
    assert out.encoding == "rgbf32" and out.header == atlas.header and out.data.shape == (ATLAS, ATLAS, 3)
    want = expand_atlas(atlas.data, _texmap(), np.asarray(photo.data, np.float32), method="landis-pc", views=3,
                        size=256)
    np.testing.assert_array_equal(out.data, want.radiance)
    assert out.data.max() > 1.0  # saturated texels expanded above LDR white
    # the inputs in any order: the same atlas once all three are in
    ctx = run_node(HdrAtlasExpander, [("photo", photo), ("atlas", atlas), ("floorplan", _floorplan())], EXP_PARAMS)
    np.testing.assert_array_equal(ctx.outputs("atlas")[0].data, want.radiance)
    # no photo or no floorplan: nothing
    assert run_node(HdrAtlasExpander, [("floorplan", _floorplan()), ("atlas", atlas)], EXP_PARAMS).published == []
    assert run_node(HdrAtlasExpander, [("photo", photo), ("atlas", atlas)], EXP_PARAMS).published == []


def test_atlas_expander_min_period_holds_the_latest_atlas_until_due_or_the_input_ends():
    ctx = RecordingContext("hdr_atlas", HdrAtlasExpander)
    node = HdrAtlasExpander(ctx, load_params(HdrAtlasExpander.Params, dict(EXP_PARAMS, min_period_s=1.0),
                                             node_id="hdr_atlas"))
    node.setup()
    (_, timer), = ctx.timers
    node.on_input("floorplan", _floorplan())
    node.on_input("photo", _photo())
    node.on_input("atlas", _ldr_atlas(stamp=1))            # t = 0: expanded at once
    ctx.clock_ns = 400_000_000
    node.on_input("atlas", _ldr_atlas(stamp=2, seed=4))    # too soon: held ...
    node.on_input("atlas", _ldr_atlas(stamp=3, seed=5))    # ... replaced by the newer one
    timer()
    assert [m.header.stamp_ns for m in ctx.outputs("atlas")] == [1]
    ctx.clock_ns = 1_100_000_000
    timer()                                                # due: the held atlas, by the timer
    timer()
    assert [m.header.stamp_ns for m in ctx.outputs("atlas")] == [1, 3]
    ctx.clock_ns = 1_200_000_000
    node.on_input("atlas", _ldr_atlas(stamp=4, seed=6))    # held ...
    node.on_input("photo", _photo())                       # a new photo alone does not re-expand
    assert [m.header.stamp_ns for m in ctx.outputs("atlas")] == [1, 3]
    node.on_input_closed("atlas")                          # ... until the atlas input ends
    node.close()
    assert [m.header.stamp_ns for m in ctx.outputs("atlas")] == [1, 3, 4]


def test_atlas_expander_counts_bad_inputs_and_goes_on(caplog):
    good = _ldr_atlas(stamp=9)
    inputs = [("floorplan", _floorplan()), ("photo", Image(Header(0, "pano"), np.zeros((8, 16, 3), np.uint8), "rgb8")),
              ("photo", _photo()),
              ("atlas", Image(Header(1, "world"), good.data[..., :3].copy(), "rgb8")),      # no alpha
              ("atlas", _ldr_atlas(stamp=2, observed=0.0)),                                 # nothing observed yet
              ("atlas", Image(Header(3, "world"), np.full((32, 32, 4), 255, np.uint8), "rgba8")),  # wrong size
              ("atlas", good)]
    with caplog.at_level("INFO", logger="hdr_atlas"):
        ctx = run_node(HdrAtlasExpander, inputs, EXP_PARAMS, node_id="hdr_atlas")
    assert [m.header.stamp_ns for m in ctx.outputs("atlas")] == [9]
    assert "bad inputs: {'photo_encoding': 1, 'atlas_encoding': 1, 'expansion': 1}" in caplog.text
    assert "expansion 1 (landis-pc)" in caplog.text


# ---------------------------------------------------------------- cubemap_renderer, HDR path

CUBE = 256
FACE = 32
CENTRE = [2.5, 2.0, 1.3]  # +X (face 0) looks at wall 1 (x = 5)


@pytest.fixture(scope="module")
def layout():
    return make_layout(FLOORPLAN, CEILING, CoarseConfig(CUBE, 0.0))


def _hdr_atlas(layout, wall: float = 5.0, base: float = 0.5, encoding: str = "rgbf32") -> Image:
    """Float linear atlas: ``base`` everywhere, wall 1 (with its padding ring) ``wall``."""
    a = np.full((layout.height, layout.width, 3), base, np.float32)
    x0, y0, w, h = layout.surfaces[1].rect
    a[y0 - PAD:y0 + h + PAD, x0 - PAD:x0 + w + PAD] = wall
    if encoding == "rgbf16":
        a = a.astype(np.float16)
    return Image(Header(5, "world"), a, encoding)


def _ldr_cube_atlas(layout) -> Image:
    a = np.full((layout.height, layout.width, 4), 255, np.uint8)
    a[..., :3] = (90, 140, 200)
    x0, y0, w, h = layout.surfaces[1].rect
    a[y0 - PAD:y0 + h + PAD, x0 - PAD:x0 + w + PAD, :3] = (255, 250, 40)
    return Image(Header(5, "world"), a, "rgba8")


CUBE_PARAMS = dict(atlas_size=CUBE, object_ids=["a"], object_positions=[CENTRE], face_size=FACE, mip_levels=3,
                   splat_m=0.3)
POINT = np.array([[3.5, 2.0, 1.3]], np.float32)  # 1 m along +X from the object


@pytest.mark.gl
@pytest.mark.graph
def test_cubemap_node_renders_an_hdr_atlas_unclipped_as_a_linear_float16_map(layout):
    ctx = run_node(CubemapRenderer, [("floorplan", _floorplan()), ("atlas", _hdr_atlas(layout, encoding="rgbf16"))],
                   dict(CUBE_PARAMS, dense=False, dtype="uint8"))
    (cube,) = ctx.outputs("envmap/a")
    assert isinstance(cube, Cubemap) and cube.linear and cube.faces.dtype == np.float16
    assert cube.faces.shape == (6, FACE, FACE, 3) and [m.faces.dtype for m in cube.mips] == [np.float16] * 2
    # the wall of radiance 5 fills the middle of +X, unclipped; the rest of the room is 0.5
    np.testing.assert_array_equal(cube.faces[0, 8:24, 8:24], 5.0)
    np.testing.assert_array_equal(cube.faces[1:, 12:20, 12:20], 0.5)
    # mips: box averages of the linear map (not of a clipped or sRGB one)
    faces = cube.faces.astype(np.float32)
    for (r, f), level in zip(prefilter(faces, 3)[1:], cube.mips):
        assert level.roughness == r
        np.testing.assert_allclose(level.faces.astype(np.float32), f, rtol=2e-3)
    # SH of the linear map, in the same units (what the compositor's lighting_from_messages uses)
    (sh,) = ctx.outputs("sh/a")
    assert isinstance(sh, SHCoefficients)
    np.testing.assert_allclose(sh.coeffs, project_cubemap(faces, 5), rtol=1e-3, atol=1e-4)
    assert (sh.coeffs[0] > 1.2 * project_cubemap(np.minimum(faces, 1.0), 5)[0]).all()  # the wall's light, unclipped


@pytest.mark.gl
@pytest.mark.graph
def test_cubemap_node_hdr_dense_model_ldr_fallback_then_hdr_cloud(layout):
    delta = BrightnessDelta(Header(2, "fisheye"), np.float32([0, -0.5, 0]), 10, True)
    ldr_pts = PointCloud(Header(1, "world"), POINT, np.uint8([[0, 255, 0]]))
    hdr_pts = HdrPointCloud(Header(1, "world"), POINT, np.float32([[7.0, 0.25, 0.0]]))
    ctx = RecordingContext("cube", CubemapRenderer)
    node = CubemapRenderer(ctx, load_params(CubemapRenderer.Params, CUBE_PARAMS, node_id="cube"))
    node.setup()
    for name, msg in [("floorplan", _floorplan()), ("points", ldr_pts), ("delta", delta),
                      ("atlas", _hdr_atlas(layout))]:
        node.on_input(name, msg)
    # before any HDR cloud: the LDR model with its delta, decoded to linear (eval hdr-envmap's hdr_coarse map)
    want = dense_linear(np.uint8([[0, 255, 0]]), [0, -0.5, 0])[0]
    np.testing.assert_allclose(ctx.outputs("envmap/a")[-1].faces[0, 15, 15].astype(np.float32), want, rtol=1e-3)
    node.on_input("hdr_points", hdr_pts)
    node.on_input("atlas", dataclasses.replace(_hdr_atlas(layout), header=Header(6, "world")))
    # then the HDR cloud's radiance, unclipped and without the LDR delta
    last = ctx.outputs("envmap/a")[-1]
    assert last.header.stamp_ns == 6
    np.testing.assert_array_equal(last.faces[0, 15, 15], np.float16([7.0, 0.25, 0.0]))
    np.testing.assert_array_equal(last.faces[0, 9, 9], 5.0)  # the wall around the splat
    node.close()
    assert node.counts["rendered_hdr"] == 2 and node.counts["rendered"] == 0


def _ldr_reference(layout, atlas: Image, points: PointCloud, delta) -> tuple[np.ndarray, np.ndarray]:
    """(uint8 faces, SH) of the LDR map straight from EnvmapRenderer, encoded as the node always has."""
    r = EnvmapRenderer(layout)
    try:
        r.set_atlas(atlas.data)
        r.set_dense(points.points, points.colors.astype(np.float32) / 255.0)
        faces = r.render(np.asarray(CENTRE, float), FACE, delta, splat_m=0.3)
    finally:
        r.release()
    return (np.clip(faces, 0, 1) * 255 + 0.5).astype(np.uint8), project_cubemap(srgb_to_linear(np.clip(faces, 0, 1)),
                                                                                 5)


@pytest.mark.gl
@pytest.mark.graph
def test_cubemap_node_ldr_path_is_unchanged_and_ignores_hdr_points(layout):
    atlas = _ldr_cube_atlas(layout)
    ldr_pts = PointCloud(Header(1, "world"), POINT, np.uint8([[0, 255, 0]]))
    delta = BrightnessDelta(Header(2, "fisheye"), np.float32([0, -0.5, 0]), 10, True)
    hdr_pts = HdrPointCloud(Header(1, "world"), POINT, np.float32([[7.0, 0.25, 0.0]]))
    base = [("floorplan", _floorplan()), ("points", ldr_pts), ("delta", delta)]
    plain = run_node(CubemapRenderer, base + [("atlas", atlas)], CUBE_PARAMS)
    mixed = run_node(CubemapRenderer, base + [("hdr_points", hdr_pts), ("atlas", atlas)], CUBE_PARAMS)
    (a,), (b,) = plain.outputs("envmap/a"), mixed.outputs("envmap/a")
    assert not a.linear and not b.linear and a.faces.dtype == np.uint8
    faces, sh = _ldr_reference(layout, atlas, ldr_pts, [0, -0.5, 0])
    np.testing.assert_array_equal(a.faces, faces)
    np.testing.assert_allclose(plain.outputs("sh/a")[0].coeffs, sh.astype(np.float32), rtol=1e-6)
    np.testing.assert_array_equal(a.faces[0, 15, 15], [0, 128, 0])  # the dense point, with delta
    # an HDR cloud does not touch an LDR map: byte-identical faces, mips and SH
    np.testing.assert_array_equal(b.faces, a.faces)
    for la, lb in zip(a.mips, b.mips):
        np.testing.assert_array_equal(la.faces, lb.faces)
    np.testing.assert_array_equal(mixed.outputs("sh/a")[0].coeffs, plain.outputs("sh/a")[0].coeffs)


# ---------------------------------------------------------------- the graph


def test_lighting_arg_swaps_the_envmap_include(monkeypatch):
    """lighting:=ldr (default) is the graph as before (launch/lighting/ldr.yaml); lighting:=hdr adds the photo and
    the two expanders and feeds the envmap node their topics; both validate."""
    from probeless.launch.graph import parse_graph
    from probeless.launch.validate import validate

    monkeypatch.chdir(REPO)  # the graph's default files are relative to the repository
    ldr = parse_graph(REPO / "launch/probeless.yaml")
    hdr = parse_graph(REPO / "launch/probeless.yaml", {"lighting": "hdr"})
    assert validate(ldr) == [] and validate(hdr) == []
    assert set(ldr.nodes) == {"rig", "slam", "undistort", "interp", "brightness", "texturer", "envmap", "compositor",
                              "video", "png"}
    assert set(hdr.nodes) == set(ldr.nodes) | {"photo", "hdr_atlas", "hdr_dense"}
    src = {k: v.source for k, v in ldr.nodes["envmap"].inputs.items()}
    assert src["atlas"] == "texturer/atlas" and "hdr_points" not in src
    src = {k: v.source for k, v in hdr.nodes["envmap"].inputs.items()}
    assert src["atlas"] == "hdr_atlas/atlas" and src["hdr_points"] == "hdr_dense/cloud"
    assert hdr.nodes["envmap"].node == "cubemap_renderer" and hdr.nodes["hdr_atlas"].params["atlas_size"] == 1024
    assert hdr.nodes["photo"].params["path"] == str(REPO / "launch/scenes/photos/convex_room.hdr")
    for g in (ldr, hdr):
        assert g.nodes["compositor"].inputs["envmap"].source == "envmap/envmaps"  # every object on one topic


@pytest.mark.gl
@pytest.mark.graph
@pytest.mark.slow
def test_pipeline_with_hdr_lighting_publishes_linear_hdr_envmaps(tmp_path):
    """launch/probeless.yaml lighting:=hdr on convex_room (its committed photo): the envmap node publishes linear
    float16 maps brighter than LDR white (the ceiling lamps), and the compositor still augments the frames."""
    from probeless.bag.reader import BagReader
    from probeless.launch.launcher import Launcher, load_checked
    from probeless.launch.replay import add_recorder

    graph = load_checked(str(REPO / "launch/probeless.yaml"),
                         {"lighting": "hdr", "scene": str(REPO / "launch/scenes/convex_room.yaml"), "seconds": 2.0,
                          "atlas_size": 512, "hdr_period_s": 60.0, "out_dir": str(tmp_path),
                          "hdr_method": "landis-pc",  # the graph, not PatchMatch (tested on its own)
                          # cheaper where nothing here looks (the nodes share 2 cores with the live rig): the model
                          # extracted every 3 s, not 1 s; the one-lookup split-sum lobe with 4 antialiasing lookups
                          "model_period_s": 3.0, "lobe": "split_sum", "aa_samples": 4})
    assert {"photo", "hdr_atlas", "hdr_dense", "envmap"} <= set(graph.nodes)
    bag = str(tmp_path / "run.mcap")
    add_recorder(graph, bag, topics=["envmap/envmaps", "hdr_atlas/atlas", "compositor/image"],
                 diagnostics=False)
    log = io.StringIO()
    assert Launcher(graph, out=log, ready_timeout=90.0).run() == 0, log.getvalue()
    with BagReader(bag) as reader:
        msgs = [(m.topic, reader.decode(m)) for m in reader.messages()]
    cubes = [m for t, m in msgs if t == "envmap/envmaps" and m.object_id == "sphere"]
    atlases = [m for t, m in msgs if t == "hdr_atlas/atlas"]
    assert atlases and all(a.encoding == "rgbf32" for a in atlases)
    assert cubes and all(c.linear and c.faces.dtype == np.float16 for c in cubes)
    faces = cubes[-1].faces.astype(np.float32)
    assert np.isfinite(faces).all() and faces.min() >= 0
    assert faces.max() > 1.5, faces.max()  # the lamps: above LDR white, which an LDR map clips at 1
    assert any(t == "compositor/image" for t, _ in msgs)
    assert "expansion 1 (landis-pc)" in log.getvalue()
    assert (tmp_path / "cubemap_net_sphere.png").exists()
