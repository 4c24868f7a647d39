"""Radiometric calibration frames from the synthetic rig: an exposure stack (bracketing) of one static fisheye
view, and a flat field, recorded through the scene's fisheye ``sensor_effects`` (response curve, white balance,
vignetting, noise) at known exposures, written as ``probeless calibrate response|vignetting`` read them.

A stack folder holds the images (8-bit PNG, RGB) and ``exposures.csv`` with a header ``file,exposure`` and one row
per image: its file name (relative to the folder) and its exposure, any unit proportional to shutter time x gain
(only ratios count). What a real camera does: fix focus, white balance and gain, keep the camera and the scene still,
step the shutter time. Auto-exposure is off while the stack is taken (each frame uses the exposure in its row).

``probeless scene bracket SCENE -o DIR`` writes one (``--flat``: a flat field, a uniform white radiance filling the
field of view, as an integrating sphere or an evenly lit diffuser over the lens gives).
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np

from probeless.cameras.radiometry_stack import EXPOSURES_CSV, write_stack
from probeless.errors import SceneError
from probeless.scene.camera_sim import CameraSim
from probeless.scene.effects_spec import CameraEffects
from probeless.scene.spec import Scene

DEFAULT_EV = [round(-4 + 2 * i / 3, 4) for i in range(14)]


def small_fisheye(scene: Scene, size: int | None) -> Scene:
    """``scene`` with a square ``size`` x ``size`` fisheye (None: as it is)."""
    if size is None:
        return scene
    return replace(scene, fisheye=replace(scene.fisheye, width=size, height=size))


def fisheye_effects(scene: Scene) -> CameraEffects:
    """The fisheye's effects with auto-exposure off (a stack is taken at set exposures)."""
    fx = scene.sensor_effects.fisheye if scene.sensor_effects is not None else CameraEffects()
    return replace(fx, auto_exposure=None)


def fisheye_radiance(scene: Scene, t: float = 0.0, cube_size: int = 256,
                     flat: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """((H, W, 3) float32 linear radiance of the fisheye view at time ``t`` (the lights' flicker at ``t``),
    (H, W, 3) the fisheye's rays). ``flat``: a uniform radiance of that value inside the field of view instead of
    the room (a flat field; nothing is rendered)."""
    from probeless.scene.rig import FISHEYE_FRAME, Rig, fisheye_model, fisheye_rays

    if flat is not None:
        rays = fisheye_rays(fisheye_model(scene), scene.fisheye.fov_deg)
        inside = np.any(rays != 0, axis=-1)
        return np.where(inside[..., None], np.float32(flat), np.float32(0)).astype(np.float32), rays
    rig = Rig(scene, envmaps=False, fisheye_cube_size=cube_size)
    try:
        return rig.renderer.render_rays(rig.fisheye_pose(t), rig.rays, rig.light_scale(t, FISHEYE_FRAME),
                                        cube_size), rig.rays
    finally:
        rig.release()


def record_stack(scene: Scene, radiance: np.ndarray, rays: np.ndarray, exposures: list[float], frames: int = 1,
                 seed: int = 0) -> list[tuple[float, np.ndarray]]:
    """(exposure, uint8 (H, W, 3)) per frame: ``frames`` frames at each exposure multiplier of ``exposures``,
    recorded by the scene's fisheye (its response, white balance, vignetting and noise; no auto-exposure)."""
    from probeless.scene.rig import fisheye_model

    model = fisheye_model(scene)
    K = model.K
    out, index = [], 0
    for e in exposures:
        if not e > 0:
            raise SceneError(f"exposure multipliers must be > 0, got {e}")
        sim = CameraSim(fisheye_effects(scene), float(e), rays[..., 2], (K[0, 2], K[1, 2]),
                        np.any(rays != 0, axis=-1), (seed, 4))
        for _ in range(frames):
            out.append((float(e), sim.record(radiance, 0.0, index)))
            index += 1
    return out


def add_bracket_parser(cmds) -> None:
    """``probeless scene bracket`` (added to ``probeless scene``'s subparsers)."""
    c = cmds.add_parser("bracket", help="an exposure stack (or --flat, a flat field) of the fisheye for "
                                        "`probeless calibrate response|vignetting`")
    c.add_argument("scene")
    c.add_argument("-o", "--output", required=True, metavar="DIR", help="folder for the PNGs and exposures.csv")
    c.add_argument("--t", type=float, default=0.0, help="scene time of the view [s] (default 0)")
    c.add_argument("--ev", type=float, nargs="+", default=DEFAULT_EV,
                   help="exposures in stops relative to the fisheye's nominal exposure (default -4 to 4.67 in "
                        "2/3-stop steps; --flat: 0)")
    c.add_argument("--frames", type=int, default=8, help="frames per exposure (default 8; averaged by the "
                                                         "calibration, which also measures the noise from them)")
    c.add_argument("--size", type=int, help="render a SIZE x SIZE fisheye instead of the scene's")
    c.add_argument("--flat", type=float, metavar="RADIANCE", help="a flat field of this linear radiance instead "
                                                                 "of the room (e.g. 0.5)")
    c.add_argument("--force", action="store_true", help="write into a folder that already has exposures.csv")
    c.set_defaults(func=cmd_bracket)
    c = cmds.add_parser("check-radiometry", help="compare a radiometry file with the scene fisheye's true response, "
                                                 "vignetting and white balance")
    c.add_argument("scene")
    c.add_argument("radiometry", metavar="FILE", help="from `probeless calibrate response|vignetting`")
    c.add_argument("--codes", type=int, nargs=2, default=[32, 245], metavar=("LO", "HI"),
                   help="code range of the response error (default 32 245)")
    c.add_argument("--json", action="store_true", help="print one JSON object")
    c.set_defaults(func=cmd_check_radiometry)


def cmd_bracket(ns: argparse.Namespace) -> int:
    """Render the view once, record it at every exposure, write the folder."""
    from probeless.scene.parse import load_scene

    out = Path(ns.output)
    if (out / EXPOSURES_CSV).exists() and not ns.force:
        raise SceneError(f"{out / EXPOSURES_CSV} already exists; pass --force to overwrite it")
    if ns.frames < 1:
        raise SceneError(f"--frames must be >= 1, got {ns.frames}")
    scene = small_fisheye(load_scene(ns.scene), ns.size)
    radiance, rays = fisheye_radiance(scene, ns.t, flat=ns.flat)
    nominal = scene.fisheye.exposure
    evs = [0.0] if ns.flat is not None and ns.ev is DEFAULT_EV else ns.ev
    stack = record_stack(scene, radiance, rays, [nominal * 2.0 ** ev for ev in evs], ns.frames)
    path = write_stack(out, stack)
    print(f"wrote {len(stack)} frame(s) and {path}")
    return 0


def true_inverse(effects: CameraEffects) -> np.ndarray:
    """(256,) the camera's true inverse response at every code (sRGB or ``x^(1/gamma)``; 1 = full well)."""
    from probeless.color import srgb_to_linear

    z = np.arange(256) / 255.0
    return srgb_to_linear(z) if effects.gamma is None else z ** effects.gamma


def radiometry_errors(scene: Scene, radiometry, codes: tuple[int, int] = (32, 245)) -> dict:
    """Max relative errors of a calibrated radiometry against the scene's fisheye: inverse response over ``codes``,
    vignetting factor over the image circle (poly model: about the principal point), white-balance gains."""
    from probeless.scene.rig import fisheye_model, fisheye_rays
    from probeless.scene.sensor_effects import vignetting_map

    fx = fisheye_effects(scene)
    lo, hi = codes
    true = true_inverse(fx)
    out = {"response_max_rel_error": float(np.max(np.abs(radiometry.inverse[:, lo:hi + 1] / true[lo:hi + 1] - 1))),
           "response_codes": [lo, hi], "valid_codes": list(radiometry.valid_codes)}
    model = fisheye_model(scene)
    rays = fisheye_rays(model, scene.fisheye.fov_deg)
    inside = np.any(rays != 0, axis=-1)
    if radiometry.vignetting is not None:
        truth = (vignetting_map(fx.vignetting, rays[..., 2], (model.K[0, 2], model.K[1, 2]))[..., 0]
                 if fx.vignetting is not None else np.ones(inside.shape))
        got = radiometry.vignetting.factor(scene.fisheye.width, scene.fisheye.height)
        out["vignetting_max_rel_error"] = float(np.max(np.abs(got[inside] / truth[inside] - 1)))
    if radiometry.gains is not None:
        wb = np.ones(3) if fx.wb_gains is None else np.asarray(fx.wb_gains, np.float64)
        out["white_balance_max_rel_error"] = float(np.max(np.abs(radiometry.gains / (wb / wb[1]) - 1)))
    return out


def cmd_check_radiometry(ns: argparse.Namespace) -> int:
    """Print :func:`radiometry_errors` (a table, or one JSON object)."""
    from probeless.cameras.radiometry import load_radiometry
    from probeless.jsonio import print_json
    from probeless.scene.parse import load_scene

    errors = radiometry_errors(load_scene(ns.scene), load_radiometry(ns.radiometry), tuple(ns.codes))
    if ns.json:
        print_json(errors)
        return 0
    for key, value in errors.items():
        print(f"{key}: {value:.4%}" if isinstance(value, float) else f"{key}: {value}")
    return 0
