"""``probeless hdr expand``: HDR expansion of an LDR coloured point cloud from one HDR photo (paper 001, §4);
``probeless hdr photo``: the HDR photo of a synthetic scene (:mod:`probeless.hdr.synthetic`), as a file.

Writes the HDR cloud (:func:`probeless.hdr.io.write_hdr_ply`: float32 linear radiance in ``red green
blue``) and the report of :func:`probeless.hdr.expand.expand_cloud` as ``OUT.json`` beside it.

``--view-positions FILE``: the cameras of the view methods, instead of placing ``--views N``:

* JSON: a list whose items are ``[x, y, z]`` or ``{"position": [x, y, z], "look_at": [x, y, z]}``;
* text: one view per line, 3 numbers (position) or 6 (position, then look-at point), separated by
  spaces or commas; blank lines and ``#`` comments are skipped.

Coordinates in the cloud's frame [m]; a view without a look-at point looks at the cloud's centroid.

``--figures DIR``: PNGs, tone-mapped for display with Reinhard ``x / (1 + x)`` per channel then sRGB
(the LDR renderings through sRGB only): ``view_XX_ldr.png`` (the LDR rendering the method saw),
``view_XX_hdr.png`` (the expanded cloud rendered from the same camera), and ``pano_before.png`` /
``pano_after.png``: cube nets (:func:`probeless.scene.preview.cube_net`) of the LDR and the expanded
cloud seen from the centre of its bounding box, both through the same tone map.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from probeless.errors import HdrError, ProbelessError

FIGURE_FACE = 256


def read_view_positions(path) -> np.ndarray:
    """(V, 2, 3) float64 rows of (position, look_at) from a ``--view-positions`` file (format in the module doc);
    a missing look-at point is NaN."""
    p = Path(path)
    if not p.is_file():
        raise HdrError(f"{p}: view positions file not found")
    text = p.read_text()
    rows = []
    try:
        if p.suffix.lower() == ".json" or text.lstrip().startswith("["):
            for item in json.loads(text):
                if isinstance(item, dict):
                    rows.append(list(item["position"]) + list(item.get("look_at") or [np.nan] * 3))
                else:
                    rows.append(list(item) + [np.nan] * 3)
        else:
            for line in text.splitlines():
                line = line.split("#", 1)[0].replace(",", " ").strip()
                if line:
                    vals = [float(v) for v in line.split()]
                    rows.append(vals + [np.nan] * 3 if len(vals) == 3 else vals)
        out = np.array(rows, np.float64)
    except (ValueError, TypeError, KeyError) as exc:
        raise HdrError(f"{p}: cannot read view positions ({exc})") from None
    if out.ndim != 2 or out.shape[1] != 6 or len(out) == 0:
        raise HdrError(f"{p}: expected one view per row of 3 or 6 numbers")
    return out.reshape(-1, 2, 3)


def read_photo_pose(path, photo_shape):
    """The :class:`~probeless.hdr.geometry.PhotoPose` of a ``--photo-pose`` JSON file: ``{"K": 3 x 3,
    "world_from_camera": 4 x 4}`` (OpenCV pinhole: x right, y down, z forward; [m] in the cloud's frame), as
    ``probeless hdr photo`` writes it beside the photo."""
    from probeless.hdr.geometry import PhotoPose

    p = Path(path)
    if not p.is_file():
        raise HdrError(f"{p}: photo pose file not found")
    try:
        d = json.loads(p.read_text())
        K = np.asarray(d["K"], np.float64)
        pose = np.asarray(d["world_from_camera"], np.float64)
    except (ValueError, TypeError, KeyError) as exc:
        raise HdrError(f"{p}: cannot read the photo pose ({exc!r}); expected {{'K': 3x3, 'world_from_camera': "
                       f"4x4}}") from None
    if K.shape != (3, 3) or pose.shape != (4, 4) or not (np.isfinite(K).all() and np.isfinite(pose).all()):
        raise HdrError(f"{p}: K must be 3 x 3 and world_from_camera 4 x 4, finite; got {K.shape}, {pose.shape}")
    if abs(np.linalg.det(pose[:3, :3]) - 1.0) > 1e-3 or K[0, 0] <= 0:
        raise HdrError(f"{p}: world_from_camera must be a rigid transform and K[0][0] > 0")
    w = photo_shape[1]
    return PhotoPose(K, pose, 0, 0, float(np.degrees(2 * np.arctan(w / 2 / K[0, 0]))), "given")


def tonemap8(radiance: np.ndarray) -> np.ndarray:
    """uint8 sRGB display of linear radiance >= 0: Reinhard ``x / (1 + x)`` per channel, then sRGB."""
    from probeless.color import to_srgb8

    r = np.maximum(np.asarray(radiance, np.float32), 0.0)
    return to_srgb8(r / (1.0 + r))


def _png(path: Path, rgb8: np.ndarray) -> None:
    import cv2

    if not cv2.imwrite(str(path), np.ascontiguousarray(rgb8[..., ::-1])):
        raise HdrError(f"{path}: cannot write the PNG")


def write_figures(out_dir, points, ldr, result) -> list[Path]:
    """The PNGs of the module docstring; returns their paths."""
    from probeless.color import to_srgb8
    from probeless.hdr.splat import SplatRenderer, point_spacing
    from probeless.scene.preview import cube_net

    d = Path(out_dir)
    d.mkdir(parents=True, exist_ok=True)
    written = []
    spacing = point_spacing(points)
    renderer = SplatRenderer()
    try:
        for i, v in enumerate(result.views):
            written.append(d / f"view_{i:02d}_ldr.png")
            _png(written[-1], to_srgb8(v.color))
            after = renderer.render(points, result.radiance, spacing, v.K, v.world_from_camera, v.size)
            written.append(d / f"view_{i:02d}_hdr.png")
            _png(written[-1], tonemap8(after.color))
        centre = 0.5 * (points.min(axis=0) + points.max(axis=0))
        for name, colors in (("pano_before", ldr), ("pano_after", result.radiance)):
            faces = renderer.render_cubemap(points, colors, spacing, centre, face_size=FIGURE_FACE)
            written.append(d / f"{name}.png")
            _png(written[-1], tonemap8(cube_net(np.stack([f.color for f in faces]))))
    finally:
        renderer.release()
    return written


class StageBars:
    """``progress(stage, done, total)`` for :func:`~probeless.hdr.expand.expand_cloud`: one rich bar per stage
    on stderr."""

    def __init__(self, enabled: bool = True):
        self.enabled, self.bar, self.tasks = enabled, None, {}

    def __enter__(self):
        if self.enabled:
            from rich.console import Console
            from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

            self.bar = Progress(TextColumn("{task.description:<9}"), BarColumn(), MofNCompleteColumn(),
                                TimeElapsedColumn(), console=Console(stderr=True))
            self.bar.__enter__()
        return self

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.__exit__(*exc)

    def __call__(self, stage: str, done: int, total: int) -> None:
        if self.bar is None:
            return
        if stage not in self.tasks:
            self.tasks[stage] = self.bar.add_task(stage, total=total)
        self.bar.update(self.tasks[stage], completed=done, total=total)


def cmd_expand(ns: argparse.Namespace) -> int:
    from probeless.hdr.expand import expand_cloud
    from probeless.hdr.io import read_cloud, require_ldr, write_hdr_ply
    from probeless.jsonio import dumps, print_json
    from probeless.pano.sources import read_panorama

    t0 = time.perf_counter()
    points, ldr, normals = read_cloud(ns.cloud)
    require_ldr(ns.cloud, ldr)
    try:
        photo = read_panorama(str(ns.photo))
    except ProbelessError as exc:
        raise HdrError(str(exc)) from None
    read_ms = (time.perf_counter() - t0) * 1e3
    out = Path(ns.output)
    if out.suffix.lower() != ".ply":
        raise HdrError(f"{out}: the output must be a .ply file")
    if not out.parent.is_dir():
        raise HdrError(f"{out.parent}: output directory not found")
    views = ns.views
    if ns.view_positions:
        rows = read_view_positions(ns.view_positions)
        rows[:, 1] = np.where(np.isnan(rows[:, 1]), points.astype(np.float64).mean(axis=0), rows[:, 1])
        views = rows
    pose = None
    if ns.photo_pose == "estimate":
        pose = "estimate"
    elif ns.photo_pose:
        pose = read_photo_pose(ns.photo_pose, photo.shape)
    with StageBars(not ns.no_progress) as bars:
        result = expand_cloud(points, ldr, photo, method=ns.method, views=views, transfer=ns.transfer,
                              normals=normals, size=ns.size, ssd_threshold=ns.ssd_threshold,
                              robust=not ns.no_robust, exposure=ns.exposure, max_lum=ns.max_lum, photo_pose=pose,
                              progress=bars)
    for w in result.report["warnings"]:
        print(f"warning: {w}", file=sys.stderr)
    t0 = time.perf_counter()
    write_hdr_ply(out, points, result.radiance, normals)
    timings = {"read": read_ms, **result.report["timings_ms"], "write": (time.perf_counter() - t0) * 1e3}
    report = {"cloud": str(ns.cloud), "photo": str(ns.photo), "output": str(out), **result.report,
              "timings_ms": timings}
    if ns.figures:
        report["figures"] = [str(p) for p in write_figures(ns.figures, points, ldr, result)]
    out.with_suffix(".json").write_text(dumps(report, indent=2) + "\n")
    if ns.json:
        print_json(report)
    else:
        r = report
        alpha = "not used" if r["alpha"] is None else f"{r['alpha']:.4g} ({r['exposure_method']})"
        peak = f", peak {r['max_lum']:.4g} ({r['max_lum_source']})" if "max_lum" in r else ""
        print(f"{out}: {r['points']} points, method {r['method']} ({r['transfer']}), alpha {alpha}{peak}, "
              f"{len(r['views'])} view(s)")
        print(f"  over-exposed {r['points_overexposed']} ({r['points_overexposed_visible']} in a view): expanded "
              f"{r['points_expanded']}, filled "
              f"{r['points_filled']}, left LDR {r['points_left_ldr']} ({r['unanchored_components']} unanchored "
              f"component(s)); max radiance {r['radiance_max']:.4g}")
        if not r["points_overexposed"]:
            print("  no over-exposed point (LDR luminance > 0.9): the cloud is unchanged")
        print("  " + ", ".join(f"{k} {v:.0f} ms" for k, v in r["timings_ms"].items()))
    return 0


def cmd_photo(ns: argparse.Namespace) -> int:
    """Write the HDR photo of :func:`probeless.hdr.synthetic.synthetic_case` as Radiance .hdr (or OpenEXR)."""
    from probeless.hdr.synthetic import synthetic_case
    from probeless.pano.sources import write_hdr_image

    out = Path(ns.output)
    if out.suffix.lower() not in (".hdr", ".exr"):
        raise HdrError(f"{out}: the photo must be a .hdr or .exr file")
    if not out.parent.is_dir():
        raise HdrError(f"{out.parent}: output directory not found")
    if not Path(ns.scene).is_file():
        raise HdrError(f"{ns.scene}: scene file not found")
    w, h = ns.size
    if not (8 <= w <= 8192 and 8 <= h <= 8192):
        raise HdrError(f"--size: expected W H in 8..8192, got {w} {h}")
    case = synthetic_case(ns.scene, photo_exposure=ns.exposure, photo_size=(w, h), photo_target=ns.target)
    try:
        write_hdr_image(out, case.photo_hdr)
    except ProbelessError as exc:
        raise HdrError(str(exc)) from None
    pose_file = out.with_suffix(".pose.json")
    pose_file.write_text(json.dumps({"K": case.photo_K.tolist(),
                                     "world_from_camera": case.photo_world_from_camera.tolist()}) + "\n")
    print(f"{out}: {w} x {h} HDR photo of {case.scene} from {np.round(case.photo_position, 3).tolist()}, "
          f"max {float(case.photo_hdr.max()):.4g} (unknown exposure {ns.exposure:g}); its pose: {pose_file}")
    return 0


def add_hdr_parser(sub) -> None:
    """``probeless hdr expand`` and ``probeless hdr photo``."""
    from probeless.hdr.methods import DEFAULT_VIEWS, METHODS

    hdr = sub.add_parser("hdr", help="HDR expansion of LDR point clouds (paper 001, section 4)")
    hsub = hdr.add_subparsers(dest="hdr_command", required=True)
    c = hsub.add_parser("expand", help="expand an LDR coloured point cloud to HDR from one HDR photo",
                        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    c.add_argument("cloud", help="LDR coloured point cloud (.ply: uchar colours sRGB, float linear 0..1; .pcd: sRGB)")
    c.add_argument("--photo", required=True, help="HDR photo of the scene (.hdr or .exr), any units")
    c.add_argument("-o", "--output", required=True, metavar="OUT.ply", help="HDR cloud; the report goes to OUT.json")
    c.add_argument("--method", choices=METHODS, default="pmatch-rgb", help="expansion method (default pmatch-rgb)")
    g = c.add_mutually_exclusive_group()
    g.add_argument("--views", type=int, default=DEFAULT_VIEWS, metavar="N",
                   help=f"views placed over the largest over-exposed clusters (default {DEFAULT_VIEWS})")
    g.add_argument("--view-positions", metavar="FILE", help="explicit view positions (format above)")
    c.add_argument("--transfer", choices=("rgb", "lum"), default="rgb", help="transfer colour or luminance")
    c.add_argument("--size", type=int, default=1024, help="view width = height [px] (default 1024)")
    c.add_argument("--ssd-threshold", type=float, default=1.0, help="PatchMatch SSD rejection t_h (default 1)")
    c.add_argument("--no-robust", action="store_true",
                   help="pmatch: keep values that disagree with their clipped cluster (the paper's raw field)")
    c.add_argument("--exposure", type=float, metavar="ALPHA",
                   help="the known exposure (cloud = ALPHA x photo); default: from geometry when the photo's pose "
                        "is known or found, else Eq. 1's histogram match")
    c.add_argument("--photo-pose", metavar="FILE",
                   help="the photo's pinhole pose, JSON {K, world_from_camera} (as 'hdr photo' writes it), or "
                        "'estimate' (RANSAC PnP on the PatchMatch correspondences; opt-in, not validated); default: "
                        "none, alpha from Eq. 1's histogram match")
    c.add_argument("--max-lum", type=float, metavar="L",
                   help="operators: the peak [cloud units] LDR white maps to (default: the photo's peak x alpha)")
    c.add_argument("--figures", metavar="DIR", help="write PNGs of the views and before/after panoramas")
    c.add_argument("--json", action="store_true", help="print the report as one JSON object")
    c.add_argument("--no-progress", action="store_true", help="no progress bars on stderr")
    c.set_defaults(func=cmd_expand)
    ph = hsub.add_parser("photo", help="the HDR photo of a synthetic scene (the truth's viewpoint; .hdr or .exr)")
    ph.add_argument("scene", help="scene YAML (launch/scenes/*.yaml)")
    ph.add_argument("-o", "--output", required=True, metavar="OUT.hdr", help="Radiance .hdr or OpenEXR file")
    ph.add_argument("--size", type=int, nargs=2, default=(320, 240), metavar=("W", "H"),
                    help="photo size [px] (default 320 240)")
    ph.add_argument("--exposure", type=float, default=0.37, help="the photo's unknown scale (default 0.37)")
    ph.add_argument("--target", choices=("overexposed", "look-at"), default="overexposed",
                    help="aim at the LDR cloud's over-exposed points or the trajectory's look-at (default overexposed)")
    ph.set_defaults(func=cmd_photo)
