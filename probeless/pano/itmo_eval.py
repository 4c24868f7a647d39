"""Paper 002's Figure 7 made quantitative (LDR vs inverse tone mapped vs true HDR): ``probeless eval itmo``.

Per true-HDR panorama: simulate an auto-exposed 8-bit camera, make the lighting maps of
:mod:`probeless.pano.itmo_maps` from its picture, light diffuse, glossy (roughness 0.1) and mirror
spheres with each, and compare with the spheres lit by the true HDR map in the same camera units
(:mod:`probeless.pano.itmo_metrics`). :func:`itmo_figure` draws the spheres as a picture grid. The
command line and its tables are :mod:`probeless.eval.itmo`.
"""

from __future__ import annotations

import cv2
import numpy as np

from probeless.pano.itmo_maps import (
    EXPOSURE_PERCENTILE,
    EXPOSURE_TARGET,
    MAPS,
    SphereLighting,
    SphereSetup,
    camera_exposure,
    ldr_stats,
    lighting_maps,
    load_case,
    make_ldr,
    render_spheres,
)
from probeless.pano.itmo_metrics import display, image_errors, mean_errors, winners
from probeless.pano.sources import default_panoramas
from probeless.pano.spheres import OBJECTS, sphere_view
from probeless.progress import progress

LABELS = {"ldr": "LDR", "paper": "paper ITMO", "paper_linear": "paper, linear", "landis": "Landis",
          "akyuz": "Akyuz", "banterle": "Banterle", "hdr": "true HDR"}
FIGURE_SIZE = 128


def evaluate_panorama(name: str, hdr: np.ndarray, setup: SphereSetup = SphereSetup(), figure: bool = False,
                      tick=lambda: None, percentile: float = EXPOSURE_PERCENTILE,
                      target: float = EXPOSURE_TARGET) -> tuple[dict, np.ndarray | None]:
    """(result, figure block or None) for one panorama; ``tick`` is called once per lighting map."""
    exposure = camera_exposure(hdr, percentile, target)
    maps = lighting_maps(hdr, exposure)
    ref_lit = SphereLighting.of(maps["hdr"], setup.diffuse_size)
    ref = render_spheres(ref_lit, setup)
    errors, rows = {}, {}
    for m in MAPS:
        lit = ref_lit if m == "hdr" else SphereLighting.of(maps[m], setup.diffuse_size)
        if m != "hdr":
            est = render_spheres(lit, setup)
            errors[m] = {o: image_errors(est[o], ref[o]) for o in OBJECTS}
        if figure:
            rows[m] = render_spheres(lit, setup, views=setup.views[:1], size=FIGURE_SIZE)
        tick()
    result = {"name": name, "exposure": exposure, **ldr_stats(hdr, exposure), "errors": errors,
              "winners": winners(errors)}
    block = _block(name, exposure, make_ldr(hdr, exposure), rows) if figure else None
    return result, block


def evaluate(paths: list[str] | None = None, setup: SphereSetup = SphereSetup(), figure: str | None = None,
             show_progress: bool = True, percentile: float = EXPOSURE_PERCENTILE,
             target: float = EXPOSURE_TARGET) -> dict:
    """Evaluate every panorama (default: :func:`default_panoramas`); with ``figure``, also write the PNG.

    The camera exposure maps the weighted ``percentile`` of luminance to ``target`` (linear).
    """
    paths = list(paths) if paths else default_panoramas()
    results, blocks = [], []
    with progress(len(paths) * len(MAPS), "ITMO evaluation (maps x panoramas)", enabled=show_progress) as tick:
        for path in paths:
            name, hdr = load_case(path)
            res, block = evaluate_panorama(name, hdr, setup, figure is not None, tick, percentile, target)
            results.append(res)
            blocks.append(block)
    overall = mean_errors([r["errors"] for r in results])
    if figure is not None:
        _write_grid(figure, blocks)
    return {"panoramas": results, "overall": {"name": "mean over panoramas", "errors": overall,
                                              "winners": winners(overall)},
            "setup": {"objects": list(OBJECTS), "views": [list(v) for v in setup.views], "size": setup.size,
                      "roughness": setup.roughness, "albedo": setup.albedo, "specular": setup.specular,
                      "diffuse_map": list(setup.diffuse_size), "exposure_percentile": percentile,
                      "exposure_target": target, "camera": "clip to 0..1, sRGB, uint8"},
            "figure": figure}


def itmo_figure(out_png: str, panoramas: list[str] | None = None, show_progress: bool = True) -> dict:
    """Write the grid (per panorama: rows LDR, each ITMO, true HDR; columns diffuse, glossy, mirror sphere,
    display-encoded at the camera exposure) to ``out_png``; returns the evaluation as :func:`evaluate`."""
    return evaluate(panoramas, figure=out_png, show_progress=show_progress)


def _text(img: np.ndarray, text: str, x: int, y: int, scale: float = 0.45) -> None:
    cv2.putText(img, text, (x, y), cv2.FONT_HERSHEY_SIMPLEX, scale, (235, 235, 235), 1, cv2.LINE_AA)


def _sphere_png(values: np.ndarray) -> np.ndarray:
    view = sphere_view(FIGURE_SIZE)
    img = np.full((FIGURE_SIZE, FIGURE_SIZE, 3), 40, np.uint8)
    img[view.mask] = np.round(display(values) * 255.0).astype(np.uint8)
    return img


def _block(name: str, exposure: float, ldr8: np.ndarray, rows: dict) -> np.ndarray:
    """One panorama's part of the figure (RGB uint8): title, the LDR input, then a row per map."""
    s, lab = FIGURE_SIZE, 110
    width = lab + len(OBJECTS) * s
    thumb = cv2.resize(ldr8, (len(OBJECTS) * s, len(OBJECTS) * s // 2), interpolation=cv2.INTER_AREA)
    head = np.zeros((44 + thumb.shape[0] + 20, width, 3), np.uint8)
    _text(head, f"{name} (exposure {exposure:.3g})", 4, 18)
    _text(head, "LDR input", 4, 40 + thumb.shape[0] // 2)
    head[28:28 + thumb.shape[0], lab:] = thumb
    for j, o in enumerate(OBJECTS):
        _text(head, o, lab + j * s + 4, head.shape[0] - 4)
    parts = [head]
    for m, objs in rows.items():
        row = np.zeros((s, width, 3), np.uint8)
        _text(row, LABELS[m], 4, s // 2)
        for j, o in enumerate(OBJECTS):
            row[:, lab + j * s: lab + (j + 1) * s] = _sphere_png(objs[o])
        parts.append(row)
    return np.vstack(parts)


def _write_grid(path: str, blocks: list[np.ndarray]) -> None:
    gap = np.zeros((blocks[0].shape[0], 8, 3), np.uint8)
    grid = np.hstack([p for b in blocks for p in (b, gap)][:-1])
    if not cv2.imwrite(path, cv2.cvtColor(grid, cv2.COLOR_RGB2BGR)):
        raise OSError(f"{path}: cannot write the PNG")
