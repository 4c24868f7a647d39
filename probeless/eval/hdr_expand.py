"""``probeless eval hdr-expand``: HDR expansion methods vs synthetic ground truth (paper 001, §6.2).

For each scene, :func:`probeless.hdr.synthetic.synthetic_case` gives a cloud with its true linear
radiance, the LDR colours ``clip(exposure * truth, 0, 1)`` and an HDR photo from another viewpoint. Every
method (``ldr``: the unexpanded LDR colours, a baseline; then the methods of
:func:`probeless.hdr.expand.expand_cloud`) expands the cloud, and we report, in cloud units
(``exposure * radiance``; 1 = LDR white):

* ``cloud_rms`` / ``cloud_rms_overexposed``: RMS over points and channels of expanded - true radiance,
  all points / the over-exposed ones (:func:`probeless.hdr.transfer.overexposed` of the LDR colours);
  ``overexposed_ratio_median``, ``overexposed_over_2x``, ``overexposed_under_half``: the over-exposed points'
  expanded / true luminance, its median and the fractions above 2 and below 1/2 (:func:`luminance_ratios`);
* ``diffuse_rms`` / ``diffuse_ssim``, ``ggx_rms`` / ``ggx_ssim``: by default (``--renderer cubemap``,
  :class:`CubemapProbes`) the cubemap path. A cubemap of each cloud
  at the scene's first virtual object (:meth:`SplatRenderer.render_cubemap`, ``--face`` px; texels no
  point covers are 0, and they are the same texels for every method since the same points are splatted)
  lights, through the IBL renderer (:class:`probeless.ibl.render.IblRenderer`, no contact shadow, exposure
  1), a UV sphere of the object's radius at its position: a ``diffuse`` one (:class:`Diffuse`, albedo 1,
  SH irradiance of the cubemap, 5 bands) and a ``ggx`` one (:class:`Metal`, colour 1, ``--roughness``,
  default 0.3), both drawn by :class:`probeless.ibl.probes.ProbeRenderer`. The GGX sphere reads a level
  prefiltered with the GGX lobe (:func:`probeless.ibl.ggx.ggx_prefilter`: split-sum radiance with n = v = r,
  weights D(h) (n.l) dω, alpha = roughness², Karis 2013) handed to the renderer as the :class:`Lighting`
  level of that roughness (the renderer's own fallback, a box mip chain, is not GGX); the renderer applies
  no Fresnel or shadowing-masking term. Each sphere is seen from two viewpoints
  (:func:`viewpoints`: ``--image`` px pinholes at 4 object radii from the centre towards the first and the
  last trajectory keyframe, so inside the room, looking at the centre). The rendering lit by the expanded
  cloud is compared with the one lit by the true cloud: RMS over the sphere's pixels (the object mask) and
  channels, and SSIM (:func:`skimage.metrics.structural_similarity`, Wang et al. 2004 settings: Gaussian
  window sigma 1.5, population covariances; data range the true rendering's maximum; per channel) averaged
  over the sphere's pixels of the SSIM map (the black background would add SSIM 1 everywhere else). The
  ``diffuse_*`` / ``ggx_*`` values are the means over the two viewpoints; ``views`` holds them per viewpoint.
* the same with ``--renderer pbgi`` (paper Table 2's rendering columns): the same two spheres, viewpoints and
  metrics, but each drawn by point-based GI (:class:`probeless.eval.hdr_pbgi.PbgiProbes`: ``lambert`` albedo 1
  and ``ggx`` f0 1 BRDFs of :mod:`probeless.pbgi.materials`, ``--variant``, ``--micro``) lit by the
  bounding-sphere hierarchy of each cloud, normals estimated once and turned towards the object; ``--tc``
  0 by default, so every cloud gets the same tree and the renderings differ by their lighting alone. The sphere
  itself is the receiver, inside the cloud, so nearby walls weigh as they do at each of its points, not as
  seen from its centre.

Where the HDR photo looks matters (``--photo-target``): a photo that also sees a ceiling lamp lets
PatchMatch match saturated white patches of the cloud to the lamp (convex_room with ``overexposed``), and
a photo that misses the window leaves nothing to transfer (l_shaped_lounge with ``look-at``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from probeless.eval.harness import add_common_options, emit
from probeless.ibl.probes import OBJECTS

BASELINE = "ldr"
GGX_ROUGHNESS = 0.3   # perceptual roughness of the GGX sphere (alpha = roughness^2)
VIEW_DISTANCE = 4.0   # camera distance from the object's centre [object radii]
VIEW_FILL = 0.8       # the sphere's silhouette spans this fraction of the image width
RENDERERS = ("cubemap", "pbgi")
UNITS = {"cloud_rms": "cloud units (exposure x linear radiance; 1 = LDR white), over points and channels",
         "diffuse_rms": "cloud units, over the pixels of a Lambertian sphere (albedo 1) lit by the cloud (its "
                        "cubemap or PBGI: 'renderer'), mean of two viewpoints",
         "ggx_rms": "cloud units, over the pixels of a GGX sphere (colour 1, roughness in 'roughness') lit by the "
                    "cloud (its cubemap or PBGI: 'renderer'), mean of two viewpoints",
         "ssim": "skimage SSIM (Gaussian sigma 1.5, population covariances, data range = the true rendering's "
                 "maximum) averaged over the sphere's pixels, mean of two viewpoints"}


def all_methods() -> tuple[str, ...]:
    from probeless.hdr.methods import METHODS

    return (BASELINE,) + tuple(METHODS)


def add_arguments(p: argparse.ArgumentParser) -> None:
    """``probeless eval hdr-expand SCENE... [--methods ...] [--views N] [--size PX] [--renderer cubemap|pbgi]
    [--json] [--figure OUT.png] [--pictures DIR]``."""
    from probeless.eval.hdr_pbgi import BSH_TC, MICRO_SIZES, VARIANTS

    p.add_argument("scenes", nargs="+", metavar="SCENE",
                   help="scene YAML files (launch/scenes/*.yaml) or HDR panoramas (.hdr/.exr) painted on a box room; "
                        "PATH@TARGET aims the photo (see load_case)")
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
    p.add_argument("--image", "--sphere", dest="image", type=int, default=128,
                   help="size of the object renderings [px], square (default 128)")
    p.add_argument("--no-robust", action="store_true",
                   help="pmatch: the paper's raw field, no rejection of values disagreeing with their clipped cluster")
    p.add_argument("--roughness", type=float, default=GGX_ROUGHNESS,
                   help=f"perceptual roughness of the GGX sphere, alpha = roughness^2 (default {GGX_ROUGHNESS})")
    p.add_argument("--renderer", choices=RENDERERS, default="cubemap",
                   help="light the spheres through each cloud's cubemap at the object (IBL) or by point-based GI "
                        "(default cubemap)")
    p.add_argument("--variant", choices=VARIANTS, default="hybrid", help="PBGI micro-buffer variant (default hybrid)")
    p.add_argument("--micro", type=int, choices=MICRO_SIZES, default=24, help="PBGI micro-buffer side (default 24)")
    p.add_argument("--tc", type=float, default=BSH_TC,
                   help=f"PBGI hierarchy's colour threshold (default {BSH_TC:g}: the same tree for every cloud; "
                        "the paper's 0.01 prunes by colour)")
    p.add_argument("--photo-pose", choices=("oracle", "estimate"), default="oracle",
                   help="pmatch: give the photo's true pose (oracle, labelled in the JSON) or let the method "
                        "estimate it from its correspondences (default oracle)")
    p.add_argument("--known-exposure", type=float, default=None, metavar="ALPHA",
                   help="give every method this exposure (cloud = ALPHA x photo) instead of estimating it")
    p.add_argument("--pictures", metavar="DIR",
                   help="write DIR/<scene>.png: each method's GGX and diffuse renderings next to the truth")
    add_common_options(p, figure=("--figure", "bar chart of the rendering RMS per method and scene"))


# --- lighting: cameras, SSIM --------------------------------------------------------------------

def viewpoints(centre, radius: float, towards, size: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """[(K, world_from_camera)] of pinholes ``size`` px square at ``VIEW_DISTANCE`` radii from ``centre``
    towards each point of ``towards`` (clamped to that point), looking at ``centre``, the sphere's
    silhouette spanning ``VIEW_FILL`` of the image width."""
    from probeless.hdr.views import camera_looking_at

    c = np.asarray(centre, np.float64)
    out = []
    for t in towards:
        d = np.asarray(t, np.float64) - c
        dist = min(VIEW_DISTANCE * radius, float(np.linalg.norm(d)))
        half = np.degrees(np.arcsin(min(radius / dist, 0.99)))
        fov = min(2.0 * np.degrees(np.arctan(np.tan(np.radians(half)) / VIEW_FILL)), 170.0)
        out.append(camera_looking_at(c + dist * d / np.linalg.norm(d), c, fov, (size, size)))
    return out


def ssim_masked(est: np.ndarray, ref: np.ndarray, mask: np.ndarray) -> float:
    """skimage SSIM (Wang et al. settings, data range ``ref.max()``) averaged over the ``mask`` pixels."""
    from skimage.metrics import structural_similarity

    _, smap = structural_similarity(est, ref, data_range=max(float(ref.max()), 1e-6), channel_axis=-1,
                                    gaussian_weights=True, sigma=1.5, use_sample_covariance=False, full=True)
    return float(smap[mask].mean())


def compare_renderings(est: dict, ref: dict) -> dict:
    """``<object>_rms`` / ``<object>_ssim`` means over the viewpoints, and ``views``: the same per viewpoint."""
    views = []
    for i in range(len(ref[OBJECTS[0]])):
        row = {}
        for kind in OBJECTS:
            (a, _), (b, inside) = est[kind][i], ref[kind][i]
            row[f"{kind}_rms"] = float(np.sqrt(np.mean((a[inside] - b[inside]) ** 2)))
            row[f"{kind}_ssim"] = ssim_masked(a, b, inside)
        views.append(row)
    means = {k: float(np.mean([v[k] for v in views])) for k in views[0]}
    return {**means, "views": views}


def luminance_ratios(est: np.ndarray, truth: np.ndarray) -> dict:
    """Over-exposed points' estimated / true luminance: ``overexposed_ratio_median`` and the fractions
    ``overexposed_over_2x`` / ``overexposed_under_half`` (None without such points)."""
    from probeless.hdr.exposure import luminance

    if not len(est):
        return {"overexposed_ratio_median": None, "overexposed_over_2x": None, "overexposed_under_half": None}
    r = luminance(est).astype(np.float64) / np.maximum(luminance(truth).astype(np.float64), 1e-12)
    return {"overexposed_ratio_median": float(np.median(r)), "overexposed_over_2x": float((r > 2).mean()),
            "overexposed_under_half": float((r < 0.5).mean())}


def rms(a: np.ndarray, b: np.ndarray) -> float | None:
    return float(np.sqrt(np.mean((a.astype(np.float64) - b) ** 2))) if len(a) else None


# --- one scene ------------------------------------------------------------------------------------

ALPHA_GOAL = 0.10       # |alpha / true alpha - 1|
EXPANDED_GOAL = 0.90    # fraction of the over-exposed points the photo sees that are expanded
OPERATORS = ("landis", "banterle", "landis-pc", "banterle-pc")


def photo_oracle(case):
    """``(PhotoPose, sees (N,) bool)``: the synthetic photo's true pinhole and the points it shows (the cloud splatted
    from it, id buffer): the scene's ground truth, independent of any method."""
    from probeless.hdr.geometry import PhotoPose, photo_visibility
    from probeless.hdr.splat import point_spacing

    h, w = case.photo_hdr.shape[:2]
    fov = float(np.degrees(2 * np.arctan(w / 2 / case.photo_K[0, 0])))
    pose = PhotoPose(np.asarray(case.photo_K), np.asarray(case.photo_world_from_camera), 0, 0, fov, "given")
    view = photo_visibility(case.points, case.ldr_colors, point_spacing(case.points), pose, (w, h))
    sees = np.zeros(len(case.points), bool)
    sees[view.point_id[view.point_id >= 0]] = True
    return pose, sees


def scene_goals(rows: dict) -> dict | None:
    """Issue 27's goals on one scene: the best PatchMatch method on each metric beats ``ldr`` and every operator on
    over-exposed cloud RMS and on GGX RMS; the best one on GGX (``best_pmatch``) has its alpha within 10 % and >= 90 %
    of the over-exposed points the photo sees expanded. None without a PatchMatch method in the run."""
    pm = [m for m in rows if m.startswith("pmatch")]
    if not pm:
        return None
    best = min(pm, key=lambda m: rows[m]["ggx_rms"])
    b = rows[best]
    rivals = [m for m in rows if m == BASELINE or m in OPERATORS]

    def beats(key):  # the best PatchMatch method on this metric against every rival
        mine = min(rows[m][key] if rows[m][key] is not None else 0.0 for m in pm)
        return all(mine < (rows[m][key] if rows[m][key] is not None else 0.0) or mine == 0.0 for m in rivals)
    frac = b["expanded_in_photo_fraction"]
    goals = {"best_pmatch": best, "beats_on_overexposed_rms": beats("cloud_rms_overexposed"),
             "beats_on_ggx": beats("ggx_rms"),
             "alpha_within_10pct": b["alpha_error"] is not None and abs(b["alpha_error"]) <= ALPHA_GOAL,
             "expanded_in_photo_90pct": frac is None or frac >= EXPANDED_GOAL}
    goals["all_met"] = all(v for k, v in goals.items() if k != "best_pmatch")
    return goals


class CubemapProbes:
    """The cubemap path: each radiance of the cloud ``points`` splatted into a cubemap at ``centre`` (``face`` px)
    lights the spheres of :class:`ProbeRenderer`; ``covered``: the texels the last cubemap's points cover (the
    same for every radiance)."""

    def __init__(self, ctx, points, centre, radius: float, roughness: float, cameras, size: int, face: int):
        from probeless.hdr.splat import SplatRenderer, point_spacing
        from probeless.ibl.probes import ProbeRenderer

        self.points, self.centre, self.face = points, centre, face
        self.spacing = point_spacing(points)
        self.splat = SplatRenderer(ctx)
        self.probes = ProbeRenderer(ctx, centre, radius, roughness, cameras, size)
        self.covered = None

    def render(self, radiance: np.ndarray) -> dict:
        """:meth:`ProbeRenderer.render` of the cubemap of the points with ``radiance``."""
        from probeless.hdr.splat import cloud_cubemap

        faces, self.covered = cloud_cubemap(self.splat, self.points, radiance, self.spacing, self.centre, self.face)
        return self.probes.render(faces)

    def scene_info(self) -> dict:
        """``cubemap_hole_fraction``: the solid-angle fraction of the cubemap no point covers."""
        from probeless.geom.cube import cube_solid_angles

        omega = cube_solid_angles(self.face)
        return {"cubemap_hole_fraction": float(omega[~self.covered].sum() / omega.sum())}

    def release(self) -> None:
        """Free both renderers' GL resources (not the shared context)."""
        self.probes.release()
        self.splat.release()


def make_probes(ctx, case, radius: float, cameras, ns):
    """The spheres of ``--renderer``: :class:`CubemapProbes` or :class:`probeless.eval.hdr_pbgi.PbgiProbes`."""
    args = (ctx, case.points, case.object_position, radius, ns.roughness, cameras, ns.image)
    if ns.renderer == "pbgi":
        from probeless.eval.hdr_pbgi import PbgiProbes

        return PbgiProbes(*args, variant=ns.variant, micro=ns.micro, tc=ns.tc)
    return CubemapProbes(*args, ns.face)


def split_target(spec: str) -> tuple[str, str | None]:
    """``PATH[@TARGET]`` -> (PATH, TARGET or None)."""
    path, _, target = str(spec).partition("@")
    return path, (target or None)


def load_case(spec: str, ns):
    """``(SyntheticCase, object radius [m], [two points the sphere is seen from])`` of one ``SCENE`` argument: a scene
    YAML (:func:`probeless.hdr.synthetic.synthetic_case`) or an HDR panorama (.hdr / .exr) painted on a box room
    (:func:`probeless.hdr.pano_room.pano_room_case`); ``@TARGET`` after either sets its photo's aim (YAML:
    ``overexposed``, ``look-at`` or ``x,y,z``; panorama: ``overexposed``, ``brightest`` or ``down``)."""
    from probeless.errors import HdrError

    path, target = split_target(spec)
    if Path(path).suffix.lower() in (".hdr", ".exr"):
        from probeless.hdr.pano_room import OBJECT_HEIGHT, ROOM, pano_room_case

        case = pano_room_case(path, photo_target=target or "overexposed", photo_exposure=ns.photo_exposure)
        c = np.array([ROOM[0] / 2, ROOM[1] / 2, OBJECT_HEIGHT])
        return case, 0.12, [c + np.array([1.5, 0.5, 0.3]), c + np.array([-1.5, -0.6, 0.3])]
    from probeless.hdr.synthetic import synthetic_case
    from probeless.scene.parse import load_scene

    aim = target or ns.photo_target
    if aim not in ("overexposed", "look-at"):
        try:
            aim = [float(v) for v in aim.split(",")]
        except ValueError:
            raise HdrError(f"{spec}: photo target must be overexposed, look-at or x,y,z") from None
    scene = load_scene(path)
    case = synthetic_case(path, frames=ns.frames, scale=ns.scale, voxel=ns.voxel, exposure=ns.exposure,
                          photo_exposure=ns.photo_exposure, photo_target=aim)
    if target:
        import dataclasses

        case = dataclasses.replace(case, scene=f"{case.scene}@{target}")
    return case, float(scene.virtual_objects[0].radius), [scene.keyframes[0].position, scene.keyframes[-1].position]


def evaluate_scene(scene_path: str, methods, ns, tick, images: dict | None = None) -> dict:
    """The scene's result; ``images`` (when given) receives {"truth" | method: renderings} for ``--pictures``."""
    from probeless.gl.context import create_context
    from probeless.hdr.expand import expand_cloud
    from probeless.hdr.transfer import overexposed

    case, radius, towards = load_case(scene_path, ns)
    cameras = viewpoints(case.object_position, radius, towards, ns.image)
    truth = case.truth_cloud_units.astype(np.float64)
    over = overexposed(case.ldr_colors)
    true_alpha = case.exposure / case.photo_exposure
    oracle = photo_oracle(case)
    in_photo = over & oracle[1]
    pose = oracle[0] if getattr(ns, "photo_pose", "oracle") == "oracle" else "estimate"
    ctx = create_context()
    probes = None
    try:
        probes = make_probes(ctx, case, radius, cameras, ns)
        ref = probes.render(truth)
        info = probes.scene_info()
        if images is not None:
            images["truth"] = ref
        tick()
        rows = {}
        for m in methods:
            if m == BASELINE:
                radiance, report, expanded = case.ldr_colors, {}, None
            else:
                res = expand_cloud(case.points, case.ldr_colors, case.photo_hdr, method=m, views=ns.views,
                                   size=ns.size, robust=not getattr(ns, "no_robust", False), photo_pose=pose,
                                   exposure=getattr(ns, "known_exposure", None))
                radiance, report = res.radiance, res.report
                expanded = res.expanded
            est = probes.render(radiance)
            if images is not None:
                images[m] = est
            alpha = report.get("alpha")
            rows[m] = {"cloud_rms": rms(radiance, truth), "cloud_rms_overexposed": rms(radiance[over], truth[over]),
                       **luminance_ratios(radiance[over], truth[over]), **compare_renderings(est, ref),
                       "alpha": alpha, "alpha_error": None if alpha is None else alpha / true_alpha - 1.0,
                       "exposure_method": report.get("exposure_method"),
                       "points_expanded": report.get("points_expanded"),
                       "points_overexposed_visible": report.get("points_overexposed_visible"),
                       "expanded_in_photo_fraction": (None if m == BASELINE or not in_photo.any() else
                                                      float(expanded[in_photo].mean())),
                       "points_filled": report.get("points_filled"), "points_rejected": report.get("points_rejected"),
                       "warnings": report.get("warnings", [])}
            tick()
    finally:
        if probes is not None:
            probes.release()
        ctx.release()
    return {"scene": case.scene, "points": int(len(case.points)), "points_overexposed": int(over.sum()),
            "points_overexposed_in_photo": int(in_photo.sum()), "true_alpha": true_alpha,
            "photo_pose": "estimated" if isinstance(pose, str) else "oracle",
            "goals": scene_goals(rows),
            "true_radiance_max": float(case.true_radiance.max()), "exposure": case.exposure,
            "photo_exposure": case.photo_exposure, "object_position": case.object_position.tolist(),
            "object_radius": radius, **info,
            "viewpoints": [{"position": pose[:3, 3].tolist(), "fov_deg": float(np.degrees(2 * np.arctan(
                ns.image / 2 / K[0, 0])))} for K, pose in cameras],
            "methods": rows}


# --- output ---------------------------------------------------------------------------------------

COLUMNS = ("cloud_rms", "cloud_rms_overexposed", "diffuse_rms", "diffuse_ssim", "ggx_rms", "ggx_ssim", "alpha_error",
           "expanded_in_photo_fraction")
_HEAD = {"cloud_rms": "cloud", "cloud_rms_overexposed": "cloud over", "diffuse_rms": "diffuse",
         "diffuse_ssim": "diff ssim", "ggx_rms": "ggx", "ggx_ssim": "ggx ssim", "alpha_error": "alpha err",
         "expanded_in_photo_fraction": "exp in photo"}


def format_table(result: dict) -> str:
    lines = [f"renderings ({result.get('renderer', 'cubemap')}): diffuse sphere (albedo 1) and GGX sphere "
             f"(roughness {result['roughness']}), two viewpoints each (mean shown); RMS in cloud units"]
    for s in result["scenes"]:
        holes = f", cubemap holes {100 * s['cubemap_hole_fraction']:.1f}%" if "cubemap_hole_fraction" in s else ""
        lines.append(f"{s['scene']}: {s['points']} points, {s['points_overexposed']} over-exposed "
                     f"({s.get('points_overexposed_in_photo', '-')} in the photo), true max "
                     f"{s['true_radiance_max']:.3g}, true alpha {s.get('true_alpha', float('nan')):.4g}, photo pose "
                     f"{s.get('photo_pose', '-')}{holes}")
        lines.append(f"  {'method':<12}" + "".join(f"{_HEAD[c]:>13}" for c in COLUMNS))
        for m, row in s["methods"].items():
            cells = "".join(f"{'-' if row.get(c) is None else format(row[c], '.4g'):>13}" for c in COLUMNS)
            lines.append(f"  {m:<12}{cells}")
        if s.get("goals"):
            g = s["goals"]
            lines.append("  goals (" + g["best_pmatch"] + "): " + ", ".join(
                f"{k} {'yes' if v else 'NO'}" for k, v in g.items() if k != "best_pmatch"))
    return "\n".join(lines)


def figure(result: dict, path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = result["scenes"]
    methods = list(scenes[0]["methods"]) if scenes else []
    fig, axes = plt.subplots(1, 3, figsize=(17, 4))
    width = 0.8 / max(1, len(methods))
    x = np.arange(len(scenes))
    for ax, kind in zip(axes, ("cloud_rms_overexposed", "diffuse_rms", "ggx_rms")):
        for i, m in enumerate(methods):
            values = [s["methods"][m][kind] for s in scenes]
            ax.bar(x + i * width, [v if v is not None and v > 0 else np.nan for v in values], width, label=m)
        ax.set_yscale("log")  # the inverse tone-mapping operators overshoot some scenes by orders of magnitude
        ax.set_xticks(x + 0.4 - width / 2, [s["scene"] for s in scenes], rotation=15)
        ax.set_ylabel(f"{kind} [cloud units]")
        ax.set_title(f"{kind.replace('_', ' ')} (log axis; 0 not drawn)")
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def tone_map(img: np.ndarray, white: float) -> np.ndarray:
    """sRGB-encoded ``img / white`` clipped to [0, 1] (the same ``white`` for every method of a column)."""
    from probeless.color import linear_to_srgb

    return np.clip(linear_to_srgb(np.clip(img / max(white, 1e-6), 0.0, 1.0)), 0.0, 1.0)


def pictures(scene: dict, images: dict, path: Path, renderer: str = "cubemap") -> None:
    """One PNG: rows truth and each method; columns GGX and diffuse from each viewpoint (tone-mapped, white =
    the 99th percentile of the truth's sphere pixels in that column)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = ["truth", *scene["methods"]]
    cols = [(kind, i) for kind in ("ggx", "diffuse") for i in range(len(images["truth"][kind]))]
    white = {}
    for kind, i in cols:
        img, mask = images["truth"][kind][i]
        white[kind, i] = float(np.percentile(img[mask], 99)) if mask.any() else 1.0
    fig, axes = plt.subplots(len(rows), len(cols), figsize=(2.0 * len(cols), 2.0 * len(rows)), squeeze=False)
    for r, name in enumerate(rows):
        for c, (kind, i) in enumerate(cols):
            ax = axes[r, c]
            ax.imshow(tone_map(images[name][kind][i][0], white[kind, i]))
            ax.set_xticks([])
            ax.set_yticks([])
            if r == 0:
                ax.set_title(f"{kind}, view {i + 1}", fontsize=9)
            if name != "truth":
                v = scene["methods"][name]["views"][i]
                ax.set_xlabel(f"rms {v[f'{kind}_rms']:.3g} ssim {v[f'{kind}_ssim']:.3f}", fontsize=7)
            if c == 0:
                ax.set_ylabel(name, fontsize=9)
    light = "PBGI from each cloud" if renderer == "pbgi" else "each cloud's cubemap"
    fig.suptitle(f"{scene['scene']}: spheres lit by {light} (white = truth's 99th pct)", fontsize=10)
    fig.tight_layout(rect=(0, 0, 1, 0.98))
    fig.savefig(path, dpi=100)
    plt.close(fig)


def run(ns: argparse.Namespace) -> int:
    from probeless.errors import HdrError
    from probeless.progress import progress

    choices = all_methods()
    methods = list(ns.methods or choices)
    unknown = [m for m in methods if m not in choices]
    if unknown:
        raise HdrError(f"unknown method {', '.join(map(repr, unknown))}; choices: {', '.join(choices)}")
    if not 0.0 <= ns.roughness <= 1.0:
        raise HdrError(f"--roughness must be in [0, 1], got {ns.roughness}")
    if ns.image < 16 or ns.face < 1:
        raise HdrError(f"--image must be >= 16 px and --face >= 1, got {ns.image}, {ns.face}")
    out_dir = Path(ns.pictures) if ns.pictures else None
    if out_dir is not None:
        out_dir.mkdir(parents=True, exist_ok=True)
    scenes = []
    with progress(len(ns.scenes) * (len(methods) + 1), "hdr-expand", enabled=not ns.no_progress) as tick:
        for path in ns.scenes:
            images = {} if out_dir is not None else None
            scene = evaluate_scene(path, methods, ns, tick, images)
            if out_dir is not None:
                scene["pictures"] = str(out_dir / f"{scene['scene']}.png")
                pictures(scene, images, Path(scene["pictures"]), ns.renderer)
                print(f"wrote {scene['pictures']}", file=sys.stderr)
            scenes.append(scene)
    result = {"methods": methods, "views": ns.views, "size": ns.size, "photo_target": ns.photo_target,
              "robust": not ns.no_robust, "renderer": ns.renderer,
              **({"pbgi": {"variant": ns.variant, "micro": ns.micro, "tc": ns.tc}} if ns.renderer == "pbgi"
                 else {"face": ns.face}),
              "image": ns.image, "roughness": ns.roughness, "units": UNITS, "scenes": scenes}
    if ns.figure:
        figure(result, ns.figure)
        result["figure"] = ns.figure
        print(f"wrote {ns.figure}", file=sys.stderr)
    return emit(ns, result, format_table, places=6)
