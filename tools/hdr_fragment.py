"""The HDR expansion on real data: Open3D's living-room fragment and a Poly Haven panorama (no ground truth).

Run: ``.venv/bin/python tools/hdr_fragment.py [--gain 2] [--methods ...] [-o docs/hdr]``

The fragment's brightest point has linear luminance 0.81, so at the paper's threshold (0.9) nothing in
it is over-exposed and every method leaves it unchanged. To show what the methods do on real geometry
and colours, its capture is made brighter first, as Eq. 1 does: ``LDR = clip(gain x linear colour, 0, 1)``
(``--gain 2`` clips about 4 % of the points), written as an 8-bit sRGB PLY. Then the shipped command,
``probeless hdr expand`` with ``--figures``, expands it once per method from
``st_fagans_interior_1k.hdr``, a photo of another room. So the result shows each method's behaviour and
the exposure matching on a real cloud, not a measured accuracy. Writes ``fragment_methods.png`` (one row
per method: cube nets of the LDR cloud from its centre, the view the method saw, the expanded cloud from
that view, and the expanded cloud's cube net; all through the same Reinhard tone map).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

from probeless.paths import REPO_ROOT, SHARED_DATA

FRAGMENT = SHARED_DATA / "pointclouds" / "open3d_fragment.pcd"
PHOTO = SHARED_DATA / "hdri" / "st_fagans_interior_1k.hdr"


def brighter_cloud(gain: float, out: Path) -> tuple[int, int]:
    """Write the fragment with ``clip(gain x linear)`` colours (sRGB PLY); (points, over-exposed points)."""
    import open3d as o3d

    from probeless.color import linear_to_srgb
    from probeless.hdr.io import read_cloud
    from probeless.hdr.transfer import overexposed
    from probeless.hdr.views import linear_colors

    points, colors, normals = read_cloud(FRAGMENT)
    ldr = np.clip(gain * linear_colors(colors), 0.0, 1.0)
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points.astype(np.float64)))
    pcd.colors = o3d.utility.Vector3dVector(linear_to_srgb(ldr.astype(np.float64)))
    if normals is not None:
        pcd.normals = o3d.utility.Vector3dVector(normals.astype(np.float64))
    o3d.io.write_point_cloud(str(out), pcd, write_ascii=False)
    return len(points), int(overexposed(ldr).sum())


def expand(cloud: Path, method: str, folder: Path, size: int) -> dict:
    out = folder / f"{method}.ply"
    cmd = [sys.executable, "-m", "probeless", "hdr", "expand", str(cloud), "--photo", str(PHOTO), "-o", str(out),
           "--method", method, "--views", "1", "--size", str(size), "--figures", str(folder / method), "--json",
           "--no-progress"]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=REPO_ROOT)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{proc.stderr}")
    return json.loads(proc.stdout)


def figure(rows: list[tuple[str, dict, Path]], path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(rows), 4, figsize=(15, 3.0 * len(rows)), squeeze=False,
                             gridspec_kw={"width_ratios": [1.333, 1, 1, 1.333]})
    for r, (method, report, d) in enumerate(rows):
        for c, (name, label) in enumerate((("pano_before.png", "LDR cloud, cube net from the centre"),
                                           ("view_00_ldr.png", "LDR view (what the method saw)"),
                                           ("view_00_hdr.png", "expanded, same view"),
                                           ("pano_after.png", "expanded, cube net from the centre"))):
            ax = axes[r, c]
            img = cv2.imread(str(d / name)) if (d / name).is_file() else None
            if img is not None:
                ax.imshow(img[..., ::-1])
            else:
                ax.text(0.5, 0.5, "per-point method:\nno view", ha="center", va="center", fontsize=9)
            ax.set_xticks([])
            ax.set_yticks([])
            if r == 0:
                ax.set_title(label, fontsize=9)
        axes[r, 0].set_ylabel(f"{method}\nalpha {report['alpha']:.3g}, max {report['radiance_max']:.3g}\n"
                              f"{report['points_expanded']} expanded, {report['points_filled']} filled", fontsize=8)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--gain", type=float, default=2.0, help="capture made brighter by this factor (default 2)")
    p.add_argument("--methods", nargs="+", default=["landis", "banterle-pc", "pmatch-lum", "pmatch-rgb"])
    p.add_argument("--size", type=int, default=512, help="view size [px] (default 512)")
    p.add_argument("-o", "--out", default=str(REPO_ROOT / "docs" / "hdr"), help="output folder (default docs/hdr)")
    ns = p.parse_args()
    out = Path(ns.out)
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="probeless-hdr-fragment-") as tmp:
        folder = Path(tmp)
        n, over = brighter_cloud(ns.gain, folder / "fragment_bright.ply")
        print(f"fragment x {ns.gain:g}: {n} points, {over} over-exposed", file=sys.stderr)
        rows = []
        for m in ns.methods:
            report = expand(folder / "fragment_bright.ply", m, folder, ns.size)
            print(json.dumps({k: report[k] for k in ("method", "alpha", "points_overexposed", "points_expanded",
                                                     "points_filled", "radiance_max", "timings_ms")}))
            rows.append((m, report, folder / m))
        path = out / "fragment_methods.png"
        figure(rows, path, f"Open3D fragment (real, Redwood), colours x {ns.gain:g} then clipped ({over} of {n} "
                           f"points over-exposed); photo: st_fagans_interior (another room, Poly Haven)")
    print(f"wrote {path}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
