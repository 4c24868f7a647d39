"""``probeless eval pbgi``: PBGI and environment-map renderings against Mitsuba 3, one bounce (paper 001, Figure 14).

For each reference room (:func:`probeless.pbgi.room.reference_room`: ``plain``, and ``red_wall`` with a saturated
red panel 30 cm from the sphere), the room's sphere is rendered in a Lambert material (albedo 0.8) and in GGX
(Fresnel 1, ``--roughness`` list, alpha = roughness^2) by Mitsuba (the truth: every room surface an area emitter
carrying the cloud's radiance, ``direct`` integrator), by our PBGI (``--variant``, ``--micro``), by the same
shading reading only the cubemap at the sphere's centre (``envmap``) and by the IBL compositor's shading of that
cubemap (``ibl``); see :mod:`probeless.pbgi.compare`. Reported per room and material: the relative RMS luminance
error of each method, raw and with the reference's Monte Carlo noise removed (``corrected``), the noise itself,
and for ``red_wall`` the same over the sphere's pixels facing the panel (``near_wall``), where colour bleeding is,
also over R, G, B instead of luminance (``near_wall_rgb``: luminance weighs red by 0.21 only). Near-wall errors are
raw (the reference's noise is in them).
``plain`` is seen from the ``front`` view, the others from the ``wall`` view (:func:`object_camera`).
The decal rooms (:mod:`probeless.pbgi.room_decals`: ``red_wall`` with a poster on the panel, a rug under the sphere
and the ceiling lamp as decals, coplanar in ``decals``, 0.5, 1 and 5 mm in front of their surfaces in
``decals_0.5mm`` ...) also report ``vs_coplanar``: the relative RMS luminance difference of the PBGI image from
the PBGI image of the coplanar room (same material; the goal: within 1 %), the ratio of their mean luminances and
that of Mitsuba's images (``reference_mean_ratio``: how much the step truly changes the light).
``pbgi_le_envmap`` per room: whether PBGI's error is at most the envmap mode's in every row (corrected and near the
panel).
Mitsuba renders are cached under ``out/cache/mitsuba/`` (``--no-cache`` renders again).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from probeless.eval.harness import add_common_options, emit

ROOMS = ("plain", "red_wall", "decals", "decals_0.5mm", "decals_1mm", "decals_5mm")
ROUGHNESS = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0)
SHOWN = ("pbgi", "envmap", "ibl", "pbgi_no_is")
VIEW = {"plain": "front", "red_wall": "wall"}  # red_wall: the side of the sphere the panel lights
VIEW.update({r: "wall" for r in ROOMS if r.startswith("decals")})


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--rooms", default=",".join(ROOMS), help=f"comma-separated reference rooms (default "
                                                              f"{','.join(ROOMS)})")
    p.add_argument("--roughness", default=",".join(f"{r:g}" for r in ROUGHNESS),
                   help="comma-separated GGX roughness values (default 0.1,...,1)")
    p.add_argument("--no-lambert", action="store_true", help="skip the Lambert sphere")
    p.add_argument("--size", type=int, default=96, help="image side [px] (default 96)")
    p.add_argument("--spp", type=int, default=1024, help="Mitsuba samples per pixel, split over two seeds "
                                                         "(default 1024)")
    p.add_argument("--micro", type=int, default=24, help="PBGI micro-buffer side (default 24)")
    p.add_argument("--supersample", type=int, default=2, help="PBGI raster texels per micro-buffer texel side; 1: "
                                                         "the paper's (default 2)")
    p.add_argument("--variant", default="hybrid", choices=("classic", "mipmapped", "hybrid"))
    p.add_argument("--no-cache", action="store_true", help="render the references again")
    p.add_argument("--pictures", metavar="DIR", help="write DIR/<room>.png: references, renderings, error maps")
    p.add_argument("--picture-rows", metavar="KEYS", help="comma-separated materials shown in the pictures, e.g. "
                                                           "lambert,ggx-0.10 (default: all)")
    add_common_options(p, figure=("--figure", "relative RMS error against roughness per method and room "
                                              "(Figure 14's numbers)"))


def _floats(text: str, what: str) -> list[float]:
    from probeless.errors import PbgiError

    try:
        return [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise PbgiError(f"{what}: expected comma-separated numbers, got {text!r}") from None


def _comparison(name: str, ns):
    from probeless.pbgi.compare import Comparison

    return Comparison(name, size=ns.size, view=VIEW[name], micro=ns.micro, variant=ns.variant, spp=ns.spp,
                      supersample=ns.supersample, cache=not ns.no_cache)


def coplanar_images(brdfs: list, ns) -> dict:
    """{material key: ((PBGI image, mask), (Mitsuba image, mask))} of the coplanar ``decals`` room (what the offset
    rooms should match; Mitsuba's own change says how much the step moves the truth)."""
    from probeless.pbgi.compare import material_key

    comp = _comparison("decals", ns)
    try:
        return {material_key(b): (comp.pbgi(b), comp.reference(b)) for b in brdfs}
    finally:
        comp.release()


def _vs_coplanar(images: dict, mask, coplanar) -> dict:
    """PBGI against coplanar PBGI (``rms``, ``mean_ratio``), and Mitsuba's mean ratio (``reference_mean_ratio``)."""
    from probeless.color import luminance
    from probeless.pbgi.compare import relative_rms

    (ours, ours_mask), (ref, ref_mask) = coplanar
    both = mask & ours_mask & ref_mask

    def ratio(a, b):
        return float(luminance(a[both]).mean() / luminance(b[both]).mean())
    return {"rms": relative_rms(images["pbgi"], ours, both), "mean_ratio": ratio(images["pbgi"], ours),
            "reference_mean_ratio": ratio(images["reference"], ref)}


def evaluate_room(name: str, brdfs: list, ns, tick, images: dict | None, coplanar: dict | None = None) -> dict:
    from probeless.pbgi.compare import material_key

    comp = _comparison(name, ns)
    try:
        target = comp.panel_target()
        rows = {}
        for brdf in brdfs:
            r = comp.render(brdf)
            row = {"errors": r.errors, "corrected": r.corrected, "noise": r.noise, "pixels": int(r.mask.sum()),
                   "seconds": r.seconds}
            if target is not None:
                from probeless.pbgi.compare import relative_rms

                near = comp.facing(r.mask, target)
                row["near_wall"] = {m: relative_rms(r.images[m], r.images["reference"], near)
                                    for m in r.errors}
                row["near_wall_rgb"] = {m: relative_rms(r.images[m], r.images["reference"], near, rgb=True)
                                        for m in r.errors}
                row["near_wall_pixels"] = int(near.sum())
            if coplanar is not None:
                row["vs_coplanar"] = _vs_coplanar(r.images, r.mask, coplanar[material_key(brdf)])
            rows[material_key(brdf)] = row
            if images is not None:
                images[material_key(brdf)] = (r.images, r.mask)
            tick()
        return {"room": name, "points": comp.n_points, "bsh_nodes": int(len(comp.bsh.nodes)),
                "far_field_holes": comp.far_holes, "materials": rows, "pbgi_le_envmap": _pbgi_wins(rows)}
    finally:
        comp.release()


def _pbgi_wins(rows: dict) -> bool:
    """PBGI's error is at most the envmap mode's in every row: corrected, and near the panel where measured."""
    ok = all(row["corrected"]["pbgi"] <= row["corrected"]["envmap"] for row in rows.values())
    return ok and all(row[k]["pbgi"] <= row[k]["envmap"] for row in rows.values()
                      for k in ("near_wall", "near_wall_rgb") if k in row)


def format_table(result: dict) -> str:
    lines = [f"relative RMS luminance error vs Mitsuba ({result['spp']} spp), reference noise removed "
             f"(raw in brackets); PBGI {result['variant']} {result['micro']}^2"]
    for room in result["rooms"]:
        lines.append(f"{room['room']}: {room['points']} points, {room['bsh_nodes']} BSH nodes")
        shown = [m for m in SHOWN if any(m in row["errors"] for row in room["materials"].values())]
        has_near = any("near_wall" in row for row in room["materials"].values())
        has_step = any("vs_coplanar" in row for row in room["materials"].values())
        lines.append(f"  {'material':<12}{'noise':>8}" + "".join(f"{m:>18}" for m in shown)
                     + ("  near wall: " + " ".join(f"{m:>7}" for m in shown[:3]) if has_near else "")
                     + ("   vs coplanar: rms  mean (Mitsuba)" if has_step else ""))
        for key, row in room["materials"].items():
            cells = "".join(f"{row['corrected'][m]:>9.3f} ({row['errors'][m]:.3f})" if m in row["errors"]
                            else f"{'-':>18}" for m in shown)
            near = ("  " + " " * 11 + " ".join(f"{row['near_wall'][m]:>7.3f}" for m in shown[:3])
                    if "near_wall" in row else "")
            st = row.get("vs_coplanar")
            step = (f"  {st['rms']:>8.4f} {st['mean_ratio']:>6.4f} ({st['reference_mean_ratio']:.4f})" if st else "")
            lines.append(f"  {key:<12}{row['noise']:>8.3f}{cells}{near}{step}")
        lines.append(f"  PBGI <= envmap in every row: {'yes' if room['pbgi_le_envmap'] else 'NO'}")
    return "\n".join(lines)


def figure(result: dict, path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rooms = result["rooms"]
    fig, axes = plt.subplots(1, len(rooms), figsize=(5.5 * len(rooms), 4), squeeze=False)
    for ax, room in zip(axes[0], rooms):
        keys = [k for k in room["materials"] if k.startswith("ggx")]
        rough = [float(k.split("-")[1]) for k in keys]
        for m, style in (("pbgi", "o-"), ("envmap", "s--"), ("ibl", "^:")):
            ax.plot(rough, [room["materials"][k]["corrected"][m] for k in keys], style, label=m)
        nois = [k for k in keys if "pbgi_no_is" in room["materials"][k]["errors"]]
        if nois:
            ax.plot([float(k.split("-")[1]) for k in nois],
                    [room["materials"][k]["corrected"]["pbgi_no_is"] for k in nois], "x", label="pbgi, no IS")
        ax.set_title(f"{room['room']}: GGX sphere")
        ax.set_xlabel("roughness")
        ax.set_ylabel("relative RMS luminance error")
        ax.grid(alpha=0.3)
        ax.legend()
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def pictures(room: str, images: dict, path: Path, keys=None) -> None:
    """Rows: materials (``keys``, default all); columns: Mitsuba, PBGI, envmap, IBL (tone-mapped), |dY| PBGI,
    |dY| envmap (0 to a quarter of the 99th-percentile luminance)."""
    import cv2

    from probeless.color import luminance, to_srgb8

    rows = []
    for key, (imgs, mask) in images.items():
        if keys and key not in keys:
            continue
        ref = imgs["reference"]
        white = float(np.percentile(luminance(ref[mask]), 99)) if mask.any() else 1.0
        tiles = [to_srgb8(np.clip(imgs[m] / white, 0, 1)) for m in ("reference", "pbgi", "envmap", "ibl")]
        for m in ("pbgi", "envmap"):
            d = np.abs(luminance(imgs[m]) - luminance(ref)) * mask / white
            tiles.append(cv2.applyColorMap(np.clip(d / 0.25 * 255, 0, 255).astype(np.uint8),
                                           cv2.COLORMAP_INFERNO)[..., ::-1])
        row = np.concatenate(tiles, 1)
        cv2.putText(row, key, (3, 12), cv2.FONT_HERSHEY_SIMPLEX, 0.35, (255, 255, 255), 1)
        rows.append(row)
    head = np.zeros((14, rows[0].shape[1], 3), np.uint8)
    w = rows[0].shape[1] // 6
    for i, t in enumerate(("Mitsuba", "PBGI", "envmap", "IBL", "|dY| PBGI", "|dY| envmap")):
        cv2.putText(head, t, (i * w + 3, 11), cv2.FONT_HERSHEY_SIMPLEX, 0.35, (255, 255, 255), 1)
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), np.concatenate([head] + rows, 0)[..., ::-1])


def run(ns: argparse.Namespace) -> int:
    from probeless.errors import PbgiError
    from probeless.pbgi.materials import Brdf
    from probeless.pbgi.room import ROOM_NAMES as KNOWN
    from probeless.progress import progress

    rooms = [r for r in ns.rooms.split(",") if r]
    unknown = [r for r in rooms if r not in KNOWN]
    if unknown or not rooms:
        raise PbgiError(f"--rooms: unknown {unknown or rooms} (known: {', '.join(KNOWN)})")
    rough = _floats(ns.roughness, "--roughness")
    if any(not 0.0 < r <= 1.0 for r in rough):
        raise PbgiError(f"--roughness values must be in (0, 1], got {rough}")
    if ns.size < 16 or ns.spp < 2:
        raise PbgiError(f"--size must be >= 16 and --spp >= 2, got {ns.size}, {ns.spp}")
    brdfs = ([] if ns.no_lambert else [Brdf("lambert", (0.8, 0.8, 0.8))]) + [Brdf("ggx", (1, 1, 1), r) for r in rough]
    out_dir = Path(ns.pictures) if ns.pictures else None
    results = []
    coplanar = coplanar_images(brdfs, ns) if any(r.startswith("decals_") for r in rooms) else None
    with progress(len(rooms) * len(brdfs), "pbgi vs mitsuba", enabled=not ns.no_progress) as tick:
        for name in rooms:
            images = {} if out_dir is not None else None
            res = evaluate_room(name, brdfs, ns, tick, images, coplanar if name.startswith("decals_") else None)
            if out_dir is not None:
                res["pictures"] = str(out_dir / f"{name}.png")
                pictures(name, images, Path(res["pictures"]),
                         [k for k in ns.picture_rows.split(",") if k] if ns.picture_rows else None)
                print(f"wrote {res['pictures']}", file=sys.stderr)
            results.append(res)
    result = {"reference": "Mitsuba 3 scalar_rgb, direct integrator (one bounce), room surfaces as area emitters "
                           "with the cloud's radiance",
              "size": ns.size, "spp": ns.spp, "micro": ns.micro, "supersample": ns.supersample,
              "variant": ns.variant, "rooms": results}
    if ns.figure:
        figure(result, ns.figure)
        print(f"wrote {ns.figure}", file=sys.stderr)
    return emit(ns, result, format_table)
