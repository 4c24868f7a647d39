"""``probeless eval hdr-envmap``: HDR coarse and dense models' environment maps vs the rig's linear truth.

Paper 003's future work with paper 001 §4: the coarse room model's atlas and the dense model are expanded to
HDR from one HDR photo (:mod:`probeless.hdr.coarse`), and the cubemap renderer draws them without clipping
(:class:`probeless.envmap.cubemap.EnvmapRenderer`, ``linear=True``), so the maps keep the real strength of
lamps and windows. Per scene:

1. the frames are rendered and replayed as ``probeless eval envmap`` does (method ``ours``:
   :func:`probeless.envmap.evaluate.render_frames`, :func:`~probeless.envmap.evaluate.replay`): **offline
   and oracle**: the coarse model is textured at the rig's *true* fisheye poses and the dense model is fused
   from RGB-D frames at their *true* poses (:class:`~probeless.envmap.dense_points.DensePoints`), no SLAM;
2. the HDR photo is :func:`probeless.hdr.synthetic.synthetic_case`'s (a linear pinhole render times an
   unknown ``photo_exposure``, the lights as at the trajectory's end) aimed by ``--photo-target``:
   ``atlas-overexposed`` (default) at the centroid of the atlas's observed over-exposed texels (what the
   upward fisheye saw saturated: lamps, windows; ``overexposed`` when there is none), ``overexposed`` at the
   RGB-D cloud's over-exposed points, ``look-at`` at the trajectory's look-at point;
3. the published ``rgba8`` atlas at the last fisheye frame is expanded (:func:`~probeless.hdr.coarse.expand_atlas`)
   and so is the dense model (:func:`~probeless.hdr.coarse.expand_dense`, its colours with Δ applied);
4. at each virtual object, at the last fisheye frame's time, three maps are rendered and scored against the
   rig's **linear** ``gt/envmap/<id>`` (:meth:`probeless.scene.rig.Rig.render_envmap`, through float16 as the
   rig publishes it) times the fisheye's exposure, i.e. in the camera's linear units (1 = LDR white):

   * ``ldr``: the ``ours`` map of ``eval envmap`` (LDR atlas + LDR dense, camera LDR), decoded to linear;
   * ``hdr_coarse``: the HDR atlas with the LDR dense model (decoded to linear) on top;
   * ``hdr``: the HDR atlas and the HDR dense model.

Metrics (every one over the whole sphere; the truth has no hole, unobserved texels of the maps count):

* ``log_rmse_stops``: solid-angle weighted RMS of ``log2(Y_est + eps) - log2(Y_true + eps)`` (CIE Y,
  ``eps`` = 1e-3), in stops;
* ``irradiance_rel_error``: :func:`probeless.envmap.metrics.sh_rel_error` of the maps' 25 SH coefficients
  (:func:`probeless.envmap.sh.project_cubemap`): the relative L2 error of the irradiance over all normals;
* ``power_ratio``: the maps' solid-angle integrals of Y, estimate / truth (the total light at the object;
  below 1: too dark);
* ``tonemapped_psnr``: :func:`probeless.envmap.metrics.envmap_psnr` of both maps Reinhard tone mapped to
  8-bit sRGB (:func:`probeless.hdr.cli.tonemap8`) [dB];
* ``peak_ratio``: the maps' largest Y, estimate / truth (a clipped lamp gives about 1 / its radiance).

What the photo sees decides what is expanded: texels the photo misses get no transfer and are filled by
Poisson from the LDR gradients. In ``light_switch`` the over-exposed texels' centroid lies between the window
and the lamp, and the 100-degree photo misses the lamp, so its strength is not recovered there. The dense
model (within 1.5 m of the objects) is rarely over-exposed in the shipped scenes: ``hdr`` and ``hdr_coarse``
then coincide.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from probeless.eval.harness import add_common_options, emit

MAPS = ("ldr", "hdr_coarse", "hdr")
METRICS = ("log_rmse_stops", "irradiance_rel_error", "power_ratio", "tonemapped_psnr", "peak_ratio")
LOG_EPS = 1e-3
PHOTO_TARGETS = ("atlas-overexposed", "overexposed", "look-at")
POSES = ("oracle: the coarse model is textured at the rig's true fisheye poses and the dense model fused from "
         "RGB-D frames at their true poses (offline replay as 'probeless eval envmap', no SLAM)")
UNITS = {"maps": "camera linear units: fisheye exposure x radiance (1 = LDR white)",
         "truth": "the rig's linear gt/envmap (float16) x fisheye exposure, at the last fisheye frame",
         "log_rmse_stops": "stops, solid-angle weighted, CIE Y + 1e-3",
         "tonemapped_psnr": "dB, Reinhard x / (1 + x) then 8-bit sRGB, peak 1"}


def add_arguments(p: argparse.ArgumentParser) -> None:
    """``probeless eval hdr-envmap SCENE... [--method M] [--photo-target T] [--json] [--figure OUT.png]``."""
    from probeless.hdr.methods import METHODS

    p.add_argument("scenes", nargs="+", metavar="SCENE", help="scene YAML files (launch/scenes/*.yaml)")
    p.add_argument("--method", choices=METHODS, default="pmatch-rgb", help="expansion method (default pmatch-rgb)")
    p.add_argument("--photo-target", choices=PHOTO_TARGETS, default=PHOTO_TARGETS[0],
                   help="aim the HDR photo at the atlas's over-exposed texels (default), the RGB-D cloud's "
                        "over-exposed points or the trajectory's look-at point (synthetic_case)")
    p.add_argument("--photo-exposure", type=float, default=0.37, help="the photo's unknown scale (default 0.37)")
    p.add_argument("--views", type=int, default=3, help="expansion views per cloud (default 3)")
    p.add_argument("--size", type=int, default=256, help="expansion view size [px] (default 256)")
    p.add_argument("--stride", type=int, default=4, help="use every n-th fisheye frame (default 4)")
    p.add_argument("--rgbd-stride", type=int, default=6, help="use every n-th RGB-D frame (default 6)")
    p.add_argument("--atlas-size", type=int, default=256, help="coarse atlas side [texels] (default 256)")
    p.add_argument("--face-size", type=int, default=64, help="cubemap face size [texels] (default 64)")
    p.add_argument("--no-dense-expansion", action="store_true",
                   help="skip the dense model's expansion (no 'hdr' map, only 'ldr' and 'hdr_coarse')")
    add_common_options(p, figure=("--figure", "bar charts of the irradiance error and log RMSE, LDR vs HDR maps"),
                       progress_help="no progress bars")


# --- metrics -------------------------------------------------------------------------------------

def _lum_and_omega(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    from probeless.geom.cube import cube_solid_angles
    from probeless.hdr.exposure import luminance

    f = np.asarray(faces, np.float32)
    return luminance(f[..., :3]).astype(np.float64), cube_solid_angles(f.shape[1])


def log_rmse_stops(est: np.ndarray, ref: np.ndarray, eps: float = LOG_EPS) -> float:
    """Solid-angle weighted RMS of the log2 CIE Y difference of two linear cubemaps (6, S, S, 3) [stops]."""
    (a, w), (b, _) = _lum_and_omega(est), _lum_and_omega(ref)
    d = np.log2(np.maximum(a, 0) + eps) - np.log2(np.maximum(b, 0) + eps)
    return float(np.sqrt((w * d * d).sum() / w.sum()))


def power_ratio(est: np.ndarray, ref: np.ndarray) -> float:
    """Solid-angle integral of CIE Y, ``est`` / ``ref`` (linear cubemaps)."""
    (a, w), (b, _) = _lum_and_omega(est), _lum_and_omega(ref)
    return float((w * a).sum() / max((w * b).sum(), 1e-300))


def peak_ratio(est: np.ndarray, ref: np.ndarray) -> float:
    """Largest CIE Y of ``est`` over that of ``ref`` (linear cubemaps)."""
    a, _ = _lum_and_omega(est)
    b, _ = _lum_and_omega(ref)
    return float(a.max() / max(b.max(), 1e-300))


def score_linear(est: np.ndarray, ref: np.ndarray) -> dict[str, float]:
    """The metrics of the module docstring of a linear cubemap ``est`` against the linear truth ``ref``."""
    from probeless.envmap import metrics as M
    from probeless.envmap.sh import project_cubemap
    from probeless.hdr.cli import tonemap8

    return {"log_rmse_stops": log_rmse_stops(est, ref),
            "irradiance_rel_error": M.sh_rel_error(project_cubemap(est), project_cubemap(ref)),
            "power_ratio": power_ratio(est, ref),
            "tonemapped_psnr": float(M.envmap_psnr(tonemap8(est), tonemap8(ref))),
            "peak_ratio": peak_ratio(est, ref)}


# --- one scene -----------------------------------------------------------------------------------

def _replayed(scene_path: str, ns):
    """(rendered frames, replay state) of method ``ours`` over the whole trajectory, maps at the last frame."""
    from probeless.envmap.evaluate import make_replay, render_frames, replay

    r = render_frames(scene_path, None, stride=ns.stride, rgbd_stride=ns.rgbd_stride, every=10 ** 9,
                      face_size=ns.face_size, show_progress=not ns.no_progress)
    state = make_replay(r, "full", atlas_size=ns.atlas_size, face_size=ns.face_size)
    replay(r, state, show_progress=not ns.no_progress, label=f"coarse {r.scene.name}")
    return r, state


def _truth(r, position, t: float) -> np.ndarray:
    """The rig's linear gt/envmap at ``position`` (through float16, as published) times the fisheye exposure."""
    faces = r.rig.render_envmap(np.asarray(position, np.float64), t).astype(np.float16).astype(np.float32)
    return faces * np.float32(r.scene.fisheye.exposure)


def _maps(renderer, pos, size, packed, points, colours, delta, hdr_atlas, dense_ldr_lin, dense_hdr):
    """{map name: (6, S, S, 3) linear cubemap} (module docstring)."""
    from probeless.color import srgb_to_linear

    has_dense = len(points) > 0
    renderer.set_atlas(packed)
    if has_dense:
        renderer.set_dense(points, colours)
    ldr = renderer.render(pos, size, delta=delta, dense=has_dense)
    out = {"ldr": srgb_to_linear(np.clip(ldr, 0.0, 1.0)).astype(np.float32)}
    renderer.set_atlas(hdr_atlas.radiance, linear=True)
    if has_dense:
        renderer.set_dense(points, dense_ldr_lin, linear=True)
    out["hdr_coarse"] = renderer.render(pos, size, dense=has_dense)
    if dense_hdr is not None:
        if has_dense:
            renderer.set_dense(points, dense_hdr.radiance, linear=True)
        out["hdr"] = renderer.render(pos, size, dense=has_dense)
    renderer.clear_dense()
    return out


def photo_target(choice: str, atlas: np.ndarray, texmap):
    """``synthetic_case``'s ``photo_target``: the choice itself, or for ``atlas-overexposed`` the centroid
    [m] of the atlas's observed core texels that are over-exposed (``overexposed`` when none is)."""
    from probeless.hdr.coarse import atlas_linear, observed_mask
    from probeless.hdr.transfer import overexposed

    if choice != "atlas-overexposed":
        return choice
    over = overexposed(atlas_linear(atlas)) & observed_mask(atlas) & texmap.core & texmap.valid
    return texmap.position[over].mean(axis=0).tolist() if over.any() else "overexposed"


def _brief(report: dict) -> dict:
    keep = ("alpha", "exposure_distance", "points", "points_overexposed", "points_expanded", "points_filled",
            "points_left_ldr", "radiance_max", "texels_observed", "texels_cloud", "texels_ring",
            "texels_ring_expanded", "texels_inpainted_or_unseen", "timings_ms")
    return {k: report[k] for k in keep if k in report}


def evaluate_scene(scene_path: str, ns) -> dict:
    """The JSON-ready result of one scene (module docstring)."""
    from probeless.envmap.cubemap import EnvmapRenderer
    from probeless.hdr.coarse import dense_linear, expand_atlas, expand_dense
    from probeless.hdr.synthetic import synthetic_case

    r, state = _replayed(scene_path, ns)
    # created while the rig's context is current: the photo and the expansion make other contexts current
    renderer = EnvmapRenderer(state.coarse.layout, ctx=r.rig.renderer.ctx)
    try:
        t = r.eval_times[-1]
        packed = state.coarse.gpu.read_packed()
        points, colours = state.dense.points()
        delta = state.delta_sum.copy()
        target = photo_target(ns.photo_target, packed, state.coarse.texmap)
        case = synthetic_case(scene_path, photo_exposure=ns.photo_exposure, photo_target=target)
        hdr_atlas = expand_atlas(packed, state.coarse.texmap, case.photo_hdr, method=ns.method, views=ns.views,
                                 size=ns.size)
        dense_hdr = None
        if not ns.no_dense_expansion and len(points):
            dense_hdr = expand_dense(points, colours, case.photo_hdr, delta=delta, method=ns.method,
                                     views=ns.views, size=ns.size)
        dense_lin = dense_linear(colours, delta) if len(points) else np.zeros((0, 3), np.float32)
        objects = {}
        for o in r.scene.virtual_objects:
            truth = _truth(r, o.position, t)
            maps = _maps(renderer, np.asarray(o.position, np.float64), ns.face_size, packed, points, colours, delta,
                         hdr_atlas, dense_lin, dense_hdr)
            objects[o.id] = {name: score_linear(m, truth) for name, m in maps.items()}
            objects[o.id]["truth_peak"] = float(_lum_and_omega(truth)[0].max())
    finally:
        renderer.release()
        state.release()
        r.rig.release()
    return {"scene": r.scene.name, "t_s": float(t), "dense_points": int(len(points)),
            "photo_exposure": case.photo_exposure, "photo_position": case.photo_position.tolist(),
            "photo_target": target, "atlas": _brief(hdr_atlas.report),
            "dense": None if dense_hdr is None else _brief(dense_hdr.report), "objects": objects}


# --- output --------------------------------------------------------------------------------------

def format_table(result: dict) -> str:
    """One row per scene, object and map."""
    lines = [f"{'scene':<18}{'object':<10}{'map':<12}" + "".join(f"{m:>22}" for m in METRICS)]
    for s in result["scenes"]:
        for o, per in s["objects"].items():
            for name in MAPS:
                if name in per:
                    lines.append(f"{s['scene']:<18}{o:<10}{name:<12}"
                                 + "".join(f"{per[name][m]:>22.4g}" for m in METRICS))
    return "\n".join(lines)


def figure(result: dict, path: str) -> None:
    """Bar charts of the irradiance error and the log RMSE per scene and object, one bar per map."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [(f"{s['scene']}/{o}", per) for s in result["scenes"] for o, per in s["objects"].items()]
    maps = [m for m in MAPS if rows and m in rows[0][1]]
    fig, axes = plt.subplots(1, 2, figsize=(12, 4))
    width = 0.8 / max(1, len(maps))
    x = np.arange(len(rows))
    for ax, metric in zip(axes, ("irradiance_rel_error", "log_rmse_stops")):
        for i, m in enumerate(maps):
            ax.bar(x + i * width, [per[m][metric] for _, per in rows], width, label=m)
        ax.set_xticks(x + 0.4 - width / 2, [name for name, _ in rows], rotation=15, fontsize=8)
        ax.set_title(metric.replace("_", " ") + " vs linear gt/envmap")
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def run(ns: argparse.Namespace) -> int:
    """Evaluate every scene, draw, print the table or one JSON object. Returns the exit status."""
    from probeless.progress import stdout_to_stderr

    scenes = []
    with stdout_to_stderr():
        for path in ns.scenes:
            scenes.append(evaluate_scene(path, ns))
    result = {"method": ns.method, "photo_target": ns.photo_target, "views": ns.views, "size": ns.size,
              "atlas_size": ns.atlas_size, "face_size": ns.face_size, "stride": ns.stride,
              "rgbd_stride": ns.rgbd_stride, "poses": POSES, "units": UNITS, "scenes": scenes}
    if ns.figure:
        figure(result, ns.figure)
        result["figure"] = ns.figure
        print(f"wrote {ns.figure}", file=sys.stderr)
    return emit(ns, result, format_table, places=6)
