"""``probeless eval hdr-expand``: HDR expansion methods vs synthetic ground truth (paper 001, §6.2).

For each scene, :func:`probeless.hdr.synthetic.synthetic_case` gives a cloud with its true linear
radiance, the LDR colours ``clip(exposure * truth, 0, 1)`` and an HDR photo from another viewpoint. Every
method (``ldr``: the unexpanded LDR colours, a baseline; then the methods of
:func:`probeless.hdr.expand.expand_cloud`) expands the cloud, and we report, in cloud units
(``exposure * radiance``; 1 = LDR white):

* ``cloud_rms`` / ``cloud_rms_overexposed``: RMS over points and channels of expanded - true radiance,
  all points / the over-exposed ones (:func:`probeless.hdr.transfer.overexposed` of the LDR colours);
* ``diffuse_rms`` / ``diffuse_ssim``, ``mirror_rms`` / ``mirror_ssim``: a cubemap of each cloud at the
  scene's first virtual object (:meth:`SplatRenderer.render_cubemap`, holes 0 in both) lights a Lambertian
  sphere (:func:`render_diffuse_sphere`, albedo 1) and a mirror sphere (:func:`render_mirror_sphere`, the
  stand-in for a glossy GGX sphere: no GGX helper exists here), seen from +X; RMS over the sphere's pixels
  of the expanded-cloud sphere minus the true-cloud sphere; SSIM (:func:`ssim_image`) with the data range
  the true sphere's maximum. One viewpoint only.

Where the HDR photo looks matters (``--photo-target``): a photo that also sees a ceiling lamp lets
PatchMatch match saturated white patches of the cloud to the lamp (convex_room with ``overexposed``), and
a photo that misses the window leaves nothing to transfer (l_shaped_lounge with ``look-at``).
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from probeless.eval.harness import add_common_options, emit

BASELINE = "ldr"
UNITS = {"cloud_rms": "cloud units (exposure x linear radiance; 1 = LDR white)",
         "diffuse_rms": "cloud units, Lambertian sphere (albedo 1) lit by the cloud's cubemap",
         "mirror_rms": "cloud units, mirror sphere (stand-in for GGX: no GGX helper) lit by the cloud's cubemap",
         "ssim": "mean SSIM, data range = the true sphere's maximum"}


def all_methods() -> tuple[str, ...]:
    from probeless.hdr.expand import METHODS

    return (BASELINE,) + tuple(METHODS)


def add_arguments(p: argparse.ArgumentParser) -> None:
    """``probeless eval hdr-expand SCENE... [--methods ...] [--views N] [--size PX] [--json] [--figure OUT.png]``."""
    p.add_argument("scenes", nargs="+", metavar="SCENE", help="scene YAML files (launch/scenes/*.yaml)")
    p.add_argument("--methods", nargs="+", metavar="METHOD",
                   help="ldr (baseline) and expand_cloud methods (default: all)")
    p.add_argument("--views", type=int, default=3, help="expansion views per cloud (default 3)")
    p.add_argument("--size", type=int, default=256, help="expansion view size [px] (default 256)")
    p.add_argument("--frames", type=int, default=8, help="RGB-D trajectory frames back-projected (default 8)")
    p.add_argument("--scale", type=float, default=0.25, help="RGB-D resolution scale (default 0.25)")
    p.add_argument("--voxel", type=float, default=0.02, help="voxel size of the cloud [m] (default 0.02)")
    p.add_argument("--exposure", type=float, default=1.0,
                   help="the cloud's exposure: LDR = clip(exposure x radiance, 0, 1) (default 1)")
    p.add_argument("--photo-exposure", type=float, default=0.37, help="the photo's unknown scale (default 0.37)")
    p.add_argument("--photo-target", choices=("overexposed", "look-at"), default="overexposed",
                   help="aim the HDR photo at the over-exposed points' centroid or the trajectory's look-at "
                        "(default overexposed; synthetic_case)")
    p.add_argument("--face", type=int, default=64, help="cubemap face size at the object [px] (default 64)")
    p.add_argument("--sphere", type=int, default=64, help="sphere image size [px] (default 64)")
    add_common_options(p, figure=("--figure", "bar chart of the sphere rendering RMS per method and scene"))


def cloud_cubemap(renderer, points, colors, spacing, position, face: int) -> np.ndarray:
    """(6, face, face, 3) float64 cubemap of the cloud's colours at ``position`` (0 where no point)."""
    views = renderer.render_cubemap(points, colors.astype(np.float32), spacing, np.asarray(position, np.float64),
                                    face)
    return np.stack([v.color for v in views]).astype(np.float64)


def spheres(faces: np.ndarray, size: int) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    from probeless.envmap.metrics import render_diffuse_sphere, render_mirror_sphere

    return {"diffuse": render_diffuse_sphere(faces, size), "mirror": render_mirror_sphere(faces, size)}


def compare_spheres(est: dict, ref: dict) -> dict[str, float]:
    from probeless.envmap.metrics import ssim_image

    out = {}
    for kind in ("diffuse", "mirror"):
        (a, inside), (b, _) = est[kind], ref[kind]
        out[f"{kind}_rms"] = float(np.sqrt(np.mean((a[inside] - b[inside]) ** 2)))
        out[f"{kind}_ssim"] = ssim_image(a, b, data_range=max(float(b.max()), 1e-6))
    return out


def rms(a: np.ndarray, b: np.ndarray) -> float | None:
    return float(np.sqrt(np.mean((a.astype(np.float64) - b) ** 2))) if len(a) else None


def evaluate_scene(scene_path: str, methods, ns, tick) -> dict:
    from probeless.hdr.expand import expand_cloud
    from probeless.hdr.splat import SplatRenderer, point_spacing
    from probeless.hdr.synthetic import synthetic_case
    from probeless.hdr.transfer import overexposed

    case = synthetic_case(scene_path, frames=ns.frames, scale=ns.scale, voxel=ns.voxel, exposure=ns.exposure,
                          photo_exposure=ns.photo_exposure, photo_target=ns.photo_target)
    truth = case.truth_cloud_units.astype(np.float64)
    over = overexposed(case.ldr_colors)
    spacing = point_spacing(case.points)
    renderer = SplatRenderer()
    try:
        ref = spheres(cloud_cubemap(renderer, case.points, truth, spacing, case.object_position, ns.face), ns.sphere)
        rows = {}
        for m in methods:
            if m == BASELINE:
                radiance, report = case.ldr_colors, {}
            else:
                res = expand_cloud(case.points, case.ldr_colors, case.photo_hdr, method=m, views=ns.views,
                                   size=ns.size)
                radiance, report = res.radiance, res.report
            est = spheres(cloud_cubemap(renderer, case.points, radiance, spacing, case.object_position, ns.face),
                          ns.sphere)
            rows[m] = {"cloud_rms": rms(radiance, truth), "cloud_rms_overexposed": rms(radiance[over], truth[over]),
                       **compare_spheres(est, ref),
                       "alpha": report.get("alpha"), "points_expanded": report.get("points_expanded"),
                       "points_filled": report.get("points_filled")}
            tick()
    finally:
        renderer.release()
    return {"scene": case.scene, "points": int(len(case.points)), "points_overexposed": int(over.sum()),
            "true_radiance_max": float(case.true_radiance.max()), "exposure": case.exposure,
            "photo_exposure": case.photo_exposure,
            "object_position": case.object_position.tolist(), "methods": rows}


def format_table(result: dict) -> str:
    cols = ("cloud_rms", "cloud_rms_overexposed", "diffuse_rms", "diffuse_ssim", "mirror_rms", "mirror_ssim")
    lines = []
    for s in result["scenes"]:
        lines.append(f"{s['scene']}: {s['points']} points, {s['points_overexposed']} over-exposed, "
                     f"true max {s['true_radiance_max']:.3g}")
        lines.append(f"  {'method':<12}" + "".join(f"{c:>23}" for c in cols))
        for m, row in s["methods"].items():
            cells = "".join(f"{'-' if row[c] is None else format(row[c], '.4g'):>23}" for c in cols)
            lines.append(f"  {m:<12}{cells}")
    return "\n".join(lines)


def figure(result: dict, path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = result["scenes"]
    methods = list(scenes[0]["methods"]) if scenes else []
    fig, axes = plt.subplots(1, 2, figsize=(12, 4))
    width = 0.8 / max(1, len(methods))
    x = np.arange(len(scenes))
    for ax, kind in zip(axes, ("diffuse_rms", "mirror_rms")):
        for i, m in enumerate(methods):
            ax.bar(x + i * width, [s["methods"][m][kind] for s in scenes], width, label=m)
        ax.set_xticks(x + 0.4 - width / 2, [s["scene"] for s in scenes], rotation=15)
        ax.set_ylabel(f"{kind} [cloud units]")
        ax.set_title(kind.replace("_", " "))
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def run(ns: argparse.Namespace) -> int:
    from probeless.errors import HdrError
    from probeless.progress import progress

    choices = all_methods()
    methods = list(ns.methods or choices)
    unknown = [m for m in methods if m not in choices]
    if unknown:
        raise HdrError(f"unknown method {', '.join(map(repr, unknown))}; choices: {', '.join(choices)}")
    scenes = []
    with progress(len(ns.scenes) * len(methods), "hdr-expand", enabled=not ns.no_progress) as tick:
        for path in ns.scenes:
            scenes.append(evaluate_scene(path, methods, ns, tick))
    result = {"methods": methods, "views": ns.views, "size": ns.size, "photo_target": ns.photo_target,
              "units": UNITS, "scenes": scenes}
    if ns.figure:
        figure(result, ns.figure)
        result["figure"] = ns.figure
        print(f"wrote {ns.figure}", file=sys.stderr)
    return emit(ns, result, format_table, places=6)
