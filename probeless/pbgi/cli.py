"""``probeless pbgi render``: one virtual object relit by a point cloud with point-based GI (paper 001, §5), as a PNG.

The cloud is the light: a .ply whose float or double red/green/blue are linear radiance (an HDR PLY of ``probeless hdr
expand``) or whose uchar colours are sRGB codes (other types are refused), or a .pcd (sRGB);
its normals are estimated when missing (:mod:`probeless.pbgi.cloud`). The object (``--object``: ``sphere`` or an
.obj/.ply mesh, ``--radius`` its bounding-sphere radius) stands at ``--position`` (default: the cloud's centroid),
seen from ``--look-from`` (default: ``4 x radius`` away on the side of the cloud's centroid) with ``--up`` up in the
image. ``--exposure auto``
maps the 99th percentile of the object's pixels (largest channel) to 0.9. The PNG is sRGB over black or over the
cloud splatted from the same camera (``--background cloud``, same exposure); ``--exr`` also writes OUT.exr with
the linear image. ``--json`` prints the report: BSH build (time, nodes), render stats, seconds per stage.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from probeless.errors import PbgiError, ProbelessError

AUTO_PERCENTILE, AUTO_TARGET = 99.0, 0.9


def _material(text: str) -> dict:
    from probeless.launch.yamlload import load_yaml_text

    try:
        value = load_yaml_text(text, "--material")
    except ProbelessError as exc:
        raise PbgiError(f"--material: {exc}") from None
    if not isinstance(value, dict):
        raise PbgiError(f"--material: expected a mapping like '{{type: diffuse}}', got {text!r}")
    return value


def _auto_exposure(color: np.ndarray, mask: np.ndarray) -> float:
    level = float(np.percentile(color[mask].max(axis=1), AUTO_PERCENTILE)) if mask.any() else 0.0
    return AUTO_TARGET / level if level > 0 else 1.0


def _background(relighter, points, radiance, K, pose, size) -> np.ndarray:
    from probeless.hdr.splat import SplatRenderer, point_spacing

    splat = SplatRenderer(relighter.renderer.ctx)
    try:
        return splat.render(points, radiance, point_spacing(points), K, pose, size).color
    finally:
        splat.release()


def _stage(timings: dict, name: str, t0: float) -> float:
    now = time.perf_counter()
    timings[name] = round(now - t0, 3)
    return now


def cmd_render(ns: argparse.Namespace) -> int:
    """Read, build, render, write (module docstring); returns 0."""
    import cv2

    from probeless.coarse.view import look_at
    from probeless.color import to_srgb8
    from probeless.jsonio import print_json
    from probeless.pano.sources import write_hdr_image
    from probeless.pbgi.cameras import facing_pose, fov_K
    from probeless.pbgi.cloud import estimate_normals, read_cloud_file
    from probeless.pbgi.relight import Relighter, pbgi_objects
    from probeless.progress import progress

    out = Path(ns.output)
    if out.suffix.lower() != ".png":
        raise PbgiError(f"{out}: the output must be a .png file")
    if not out.parent.is_dir():
        raise PbgiError(f"{out.parent}: output directory not found")
    if ns.size < 8 or ns.size > 8192 or not ns.radius > 0 or not 1 < ns.fov < 179:
        raise PbgiError(f"--size must be in 8..8192, --radius > 0, --fov in (1, 179); got {ns.size}, {ns.radius}, "
                        f"{ns.fov}")
    material = _material(ns.material)
    timings, t = {}, time.perf_counter()
    with progress(4, "pbgi render", enabled=not ns.no_progress, transient=True) as tick:
        points, radiance, normals = read_cloud_file(ns.cloud)
        centroid = points.astype(np.float64).mean(axis=0)
        position = centroid if ns.position is None else np.asarray(ns.position, np.float64)
        spec = {"id": "object", "mesh": ns.object, "position": position.tolist(), "radius": ns.radius,
                "material": material, "contact_shadow": False}
        objects = pbgi_objects([spec])
        if normals is None:
            normals = estimate_normals(points, centroid)
        t = _stage(timings, "read", t)
        tick()
        relighter = Relighter(objects, mode=ns.mode, near_radius=ns.near_radius, variant=ns.variant, micro=ns.micro,
                              supersample=ns.supersample)
        try:
            report = relighter.set_cloud(points, radiance, normals)
            t = _stage(timings, "bsh", t)
            tick()
            pose = (facing_pose(position, ns.radius, centroid, up=ns.up) if ns.look_from is None else
                    look_at(np.asarray(ns.look_from, np.float64), position, up=np.asarray(ns.up, np.float64)))
            K = fov_K(ns.size, ns.size, ns.fov)
            relit = relighter.render(K, pose, ns.size, ns.size)
            t = _stage(timings, "render", t)
            tick()
            exposure = _auto_exposure(relit.color, relit.mask) if ns.exposure is None else ns.exposure
            image = np.zeros((ns.size, ns.size, 3), np.float32)
            if ns.background == "cloud":
                image = _background(relighter, points, radiance, K, pose, (ns.size, ns.size))
            image[relit.mask] = relit.color[relit.mask]
            image *= exposure
        finally:
            relighter.release()
        if not cv2.imwrite(str(out), np.ascontiguousarray(to_srgb8(image)[..., ::-1])):
            raise PbgiError(f"{out}: cannot write the PNG")
        if ns.exr:
            write_hdr_image(out.with_suffix(".exr"), image)
        _stage(timings, "write", t)
        tick()
    result = {"cloud": str(ns.cloud), "output": str(out), "points": len(points), "mode": ns.mode,
              "variant": ns.variant, "micro": ns.micro, "position": position.round(4).tolist(),
              "exposure": exposure, "object_pixels": int(relit.mask.sum()), "seconds": timings,
              "bsh": None if report is None else {"nodes": report.n_nodes_pruned, "clusters": report.n_clusters,
                                                   "voxel": report.voxel, "spacing": report.spacing,
                                                   "seconds": round(report.total, 3)},
              "render": [{k: v for k, v in vars(s).items()} for s in relit.stats]}
    if ns.json:
        print_json(result)
    else:
        bsh = "" if report is None else f", BSH {report.n_nodes_pruned} nodes in {report.total:.2f} s"
        print(f"{out}: {result['object_pixels']} object pixels, {ns.mode}/{ns.variant} micro {ns.micro}, exposure "
              f"{exposure:.4g}{bsh}; " + ", ".join(f"{k} {v:.2f} s" for k, v in timings.items()))
    return 0


def add_pbgi_parser(sub) -> None:
    """``probeless pbgi render``."""
    from probeless.pbgi.materials import material_help
    from probeless.pbgi.modes import MODES

    pbgi = sub.add_parser("pbgi", help="point-based global illumination of virtual objects (paper 001, section 5)")
    psub = pbgi.add_subparsers(dest="pbgi_command", required=True)
    c = psub.add_parser("render", help="render one object lit by a point cloud", description=__doc__,
                        epilog=material_help(), formatter_class=argparse.RawDescriptionHelpFormatter)
    c.add_argument("cloud", help="point cloud (.ply: float/double colours = linear radiance, uchar = sRGB; .pcd: "
                                 "sRGB)")
    c.add_argument("-o", "--output", required=True, metavar="OUT.png", help="sRGB 8-bit PNG")
    c.add_argument("--object", default="sphere", help="'sphere' or a mesh (.obj, .ply) (default sphere)")
    c.add_argument("--position", type=float, nargs=3, metavar=("X", "Y", "Z"), help="centre [m] (default: centroid)")
    c.add_argument("--radius", type=float, default=0.15, help="bounding-sphere radius [m] (default 0.15)")
    c.add_argument("--material", default="{type: diffuse, albedo: [0.8, 0.8, 0.8]}",
                   help="material mapping as in the objects param (types and keys: see the end of this help; "
                        "alpha = roughness^2), e.g. '{type: principled, base_color: [0.8, 0.2, 0.2], roughness: "
                        "0.3, metalness: 0}' (default diffuse white)")
    c.add_argument("--look-from", type=float, nargs=3, metavar=("X", "Y", "Z"),
                   help="camera position [m] (default: 4 radii away towards the cloud's centroid)")
    c.add_argument("--up", type=float, nargs=3, default=(0.0, 0.0, 1.0), metavar=("X", "Y", "Z"),
                   help="the image's up direction in the cloud's frame (default 0 0 1)")
    c.add_argument("--fov", type=float, default=40.0, help="horizontal field of view [deg] (default 40)")
    c.add_argument("--size", type=int, default=256, help="image width = height [px] (default 256)")
    c.add_argument("--variant", choices=("classic", "mipmapped", "hybrid"), default="hybrid")
    c.add_argument("--micro", type=int, choices=(16, 24, 32), default=24, help="micro-buffer side (default 24)")
    c.add_argument("--supersample", type=int, choices=(1, 2, 3, 4), default=2,  # probeless.pbgi.render.SUPERSAMPLE
                   help="micro-buffer raster texels per texel side; 1: the paper's (default 2)")
    c.add_argument("--mode", choices=MODES, default="full", help="full | near_field | envmap (default full)")
    c.add_argument("--near-radius", type=float, default=1.0, help="near_field radius [m] (default 1)")
    c.add_argument("--exposure", type=float, help="cloud units -> image (default: auto, p99 of the object -> 0.9)")
    c.add_argument("--background", choices=("black", "cloud"), default="black", help="behind the object")
    c.add_argument("--exr", action="store_true", help="also write OUT.exr (linear float)")
    c.add_argument("--json", action="store_true", help="print the report as one JSON object")
    c.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    c.set_defaults(func=cmd_render)
