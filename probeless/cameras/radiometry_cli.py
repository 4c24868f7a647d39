"""``probeless calibrate response`` and ``probeless calibrate vignetting``: the radiometric camera model
(probeless.cameras.radiometry) from an exposure stack and a flat field (docs/cameras/radiometry.md)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from probeless.errors import CalibrationError


def add_radiometry_parsers(cs: Any) -> None:
    """Add ``response`` and ``vignetting`` to ``probeless calibrate``'s subparsers."""
    r = cs.add_parser("response", help="inverse response curve per channel from an exposure stack (Debevec-Malik)")
    r.add_argument("--stack", required=True, metavar="DIR",
                   help="folder of images of a static scene and exposures.csv (file,exposure)")
    r.add_argument("-o", "--output", required=True, metavar="OUT.yaml", help="radiometry file to write")
    r.add_argument("--max-pixels", type=int, default=5000, help="pixels sampled (default 5000)")
    r.add_argument("--force", action="store_true", help="overwrite OUT")
    r.set_defaults(func=cmd_response)

    v = cs.add_parser("vignetting", help="vignetting and white balance from a flat field (needs the response)")
    v.add_argument("--flat", required=True, metavar="DIR",
                   help="folder of flat-field images (one exposure) and exposures.csv")
    v.add_argument("--radiometry", required=True, metavar="IN.yaml",
                   help="a radiometry file with the response (`probeless calibrate response`)")
    v.add_argument("-o", "--output", metavar="OUT.yaml", help="file to write (default: update IN.yaml)")
    v.add_argument("--center", type=float, nargs=2, metavar=("CX", "CY"),
                   help="vignetting centre [px] (default: fitted)")
    v.add_argument("--terms", type=int, default=3, choices=(1, 2, 3), help="k1 .. k3 terms (default 3)")
    v.add_argument("--no-white-balance", action="store_true",
                   help="the flat field is not neutral: fit no white balance")
    v.add_argument("--force", action="store_true", help="overwrite OUT (when it is not IN)")
    v.set_defaults(func=cmd_vignetting)


def _check_output(path: str, force: bool) -> Path:
    out = Path(path)
    if out.exists() and not force:
        raise CalibrationError(f"{out} already exists; pass --force to overwrite it")
    return out


def cmd_response(ns: argparse.Namespace) -> int:
    """Read the stack, fit, print the curve at a few codes, write the file."""
    from probeless.cameras.radiometry import Radiometry, save_radiometry
    from probeless.cameras.radiometry_calibrate import average_frames, calibrate_response
    from probeless.cameras.radiometry_stack import read_stack

    out = _check_output(ns.output, ns.force)
    images, exposures, _ = read_stack(ns.stack)
    means, noise, ts = average_frames(images, exposures)
    fit = calibrate_response(means, ts, noise=noise, max_pixels=ns.max_pixels)
    inverse = np.maximum.accumulate(fit.inverse, axis=1)
    per = len(images) // len(ts)
    print(f"response: {len(images)} image(s) at {len(ts)} exposure(s) ({per} per exposure on average), "
          f"{fit.pixels} pixels; codes {fit.valid_codes[0]}..{fit.valid_codes[1]} measured"
          + ("" if noise is not None else " (one frame per exposure: noise not measured, take >= 4)"))
    for z in (32, 64, 128, 192):
        print(f"  code {z}: linear " + " ".join(f"{c}={inverse[i, z]:.5f}" for i, c in enumerate("rgb")))
    for note in fit.notes:
        print(f"  note: {note}")
    save_radiometry(out, Radiometry(inverse, fit.valid_codes), {"report": {"response": {
        "method": "debevec-malik, every sampled pixel, lambda 3", "stack": str(ns.stack),
        "images": len(images), "exposures": len(ts), "pixels": fit.pixels,
        "noise_measured": noise is not None, "notes": list(fit.notes)}}})
    print(f"wrote {out}")
    return 0


def cmd_vignetting(ns: argparse.Namespace) -> int:
    """Linearise the flat field with the file's response, fit, write the file (with the old response)."""
    from dataclasses import replace

    import yaml

    from probeless.cameras.radiometry import Vignetting, load_radiometry, save_radiometry
    from probeless.cameras.radiometry_calibrate import calibrate_flat_field
    from probeless.cameras.radiometry_stack import read_stack

    source = Path(ns.radiometry)
    out = Path(ns.output) if ns.output else source
    if out.resolve() != source.resolve():
        _check_output(str(out), ns.force)
    radiometry = load_radiometry(source)
    images, exposures, _ = read_stack(ns.flat)
    if len(set(exposures)) != 1:
        raise CalibrationError(f"{ns.flat}: a flat field is taken at one exposure, got {len(set(exposures))}")
    fit = calibrate_flat_field(images, radiometry.inverse, terms=ns.terms,
                               center=tuple(ns.center) if ns.center else None)
    h, w = images[0].shape[:2]
    print(f"vignetting: {len(images)} frame(s) {w}x{h}, {fit.pixels} pixels fitted, RMS residual {fit.rms:.2%}")
    print(f"  V = 1 + k1 r^2 + k2 r^4 + k3 r^6: k = [{', '.join(f'{k:.5f}' for k in fit.coeffs)}], centre "
          f"({fit.center[0]:.1f}, {fit.center[1]:.1f}) px")
    gains = radiometry.gains if ns.no_white_balance else fit.gains
    if gains is not None:
        print(f"  white balance (relative to green): r {gains[0]:.4f}, b {gains[2]:.4f}")
    for note in fit.notes:
        print(f"  note: {note}")
    with open(source, encoding="utf-8") as f:
        old_report = (yaml.safe_load(f) or {}).get("report", {})
    report = dict(old_report if isinstance(old_report, dict) else {})
    report["vignetting"] = {"flat": str(ns.flat), "frames": len(images), "pixels": fit.pixels, "rms": fit.rms,
                            "center_fitted": ns.center is None, "notes": list(fit.notes)}
    vig = Vignetting(tuple(float(k) for k in fit.coeffs), fit.center, w, h)
    save_radiometry(out, replace(radiometry, vignetting=vig, gains=gains), {"report": report})
    print(f"wrote {out}")
    return 0
