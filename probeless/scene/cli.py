"""``probeless scene check | render | preview``: validate, pre-render to a bag, and picture a scene file."""

from __future__ import annotations

import argparse
import json
import time
from collections import defaultdict
from pathlib import Path

from probeless import __version__
from probeless.errors import SceneError
from probeless.progress import progress as progress_bar


def add_scene_parser(sub) -> None:
    """Add the ``scene`` command and its subcommands to an argparse subparsers object."""
    scene = sub.add_parser("scene", help="synthetic scenes: check, render to a bag, preview")
    cmds = scene.add_subparsers(dest="scene_command", required=True)
    c = cmds.add_parser("check", help="validate a scene file and print a summary")
    c.add_argument("scene")
    c.set_defaults(func=cmd_check)
    c = cmds.add_parser("render", help="render a scene's whole sequence to an MCAP recording")
    c.add_argument("scene")
    c.add_argument("-o", "--output", required=True, metavar="OUT.mcap")
    c.add_argument("--id", default="rig", help="node id the topics are recorded under (topic = ID/output)")
    c.add_argument("--duration", type=float, help="render this much scene time [s] (default: whole trajectory)")
    c.add_argument("--envmap-size", type=int, default=64, help="ground-truth cubemap face size [texels]")
    c.add_argument("--no-envmaps", action="store_true", help="skip the ground-truth cubemaps")
    c.add_argument("--compression", choices=("lz4", "zstd", "none"), default="lz4")
    c.add_argument("--force", action="store_true", help="overwrite OUT.mcap")
    c.set_defaults(func=cmd_render)
    c = cmds.add_parser("preview", help="PNG contact sheet: RGB, depth, fisheye and a ground-truth cubemap net")
    c.add_argument("scene")
    c.add_argument("--t", type=float, default=0.0, help="scene time [s]")
    c.add_argument("-o", "--output", required=True, metavar="SHEET.png")
    c.add_argument("--object", help="virtual object whose cubemap is shown (default: the first)")
    c.add_argument("--envmap-size", type=int, default=128, help="cubemap face size [texels]")
    c.set_defaults(func=cmd_preview)
    c = cmds.add_parser("compare", help="PNG: RGB, depth and fisheye of several scene files (e.g. clean vs realistic)")
    c.add_argument("scenes", nargs="+", metavar="SCENE")
    c.add_argument("--t", type=float, default=0.0, help="scene time [s]")
    c.add_argument("-o", "--output", required=True, metavar="SHEET.png")
    c.set_defaults(func=cmd_compare)
    from probeless.scene.rig_bracket import add_bracket_parser

    add_bracket_parser(cmds)  # probeless scene bracket: radiometric calibration frames


def cmd_check(ns: argparse.Namespace) -> int:
    from probeless.scene.parse import load_scene
    from probeless.scene.rig import frame_schedule

    s = load_scene(ns.scene)
    events = frame_schedule(s)
    n_rgbd = sum(e.kind == "rgbd" for e in events)
    print(f"{ns.scene}: scene {s.name!r} OK")
    print(f"  room: {len(s.floorplan)} walls, ceiling {s.ceiling_height} m, {len(s.windows)} window(s), "
          f"{len(s.lights)} light(s), {len(s.furniture)} furniture, virtual objects: "
          f"{', '.join(o.id for o in s.virtual_objects) or '-'}")
    print(f"  sequence: {s.duration:.2f} s, {n_rgbd} RGB-D frames at {s.rgbd.fps:g} Hz, "
          f"{len(events) - n_rgbd} fisheye frames at {s.fisheye.fps:g} Hz")
    if s.sensor_effects is not None:
        fx = s.sensor_effects
        on = [f"{cam}.{k}" for cam in ("rgbd", "fisheye") for k, v in vars(getattr(fx, cam)).items()
              if v is not None and k != "exposure_time_s"] + [k for k in ("flicker", "depth") if getattr(fx, k)]
        print(f"  sensor effects (seed {fx.seed}): {', '.join(on) or 'none'}")
    if s.given is not None:
        e = _told_errors(s)
        print(f"  told (given, seed {s.given.seed}): floorplan vertices {e['vertex_min_m'] * 100:.1f}.."
              f"{e['vertex_max_m'] * 100:.1f} cm off, ceiling {e['ceiling_m'] * 100:+.1f} cm; fisheye_from_rgbd "
              f"{e['extrinsics_m'] * 100:.2f} cm / {e['extrinsics_deg']:.2f} deg off; fisheye fx {e['fx_rel']:+.2%}, "
              f"fy {e['fy_rel']:+.2%}, centre ({e['cx_px']:+.2f}, {e['cy_px']:+.2f}) px; clock "
              f"{e['clock_s'] * 1000:+.1f} ms")
    return 0


def _told_errors(scene) -> dict:
    from probeless.scene.given import GivenRig, given_rig, told_errors
    from probeless.scene.rig import FISHEYE_FRAME, fisheye_model

    info = fisheye_model(scene).to_camera_info(FISHEYE_FRAME)
    truth = GivenRig(scene.floorplan, scene.ceiling_height, scene.fisheye_from_rgbd, info, 0.0)
    return told_errors(truth, given_rig(scene.given, scene.floorplan, scene.ceiling_height, scene.fisheye_from_rgbd,
                                        info))


def cmd_render(ns: argparse.Namespace) -> int:
    from probeless.bag.writer import BagWriter
    from probeless.provenance import git_revision
    from probeless.scene.extends import scene_yaml
    from probeless.scene.parse import load_scene
    from probeless.scene.rig import Rig, frame_schedule
    from probeless.wire import encode

    scene = load_scene(ns.scene)
    if ns.duration is not None and not ns.duration > 0:
        raise SceneError(f"--duration must be > 0, got {ns.duration}")
    events = frame_schedule(scene, ns.duration)
    params = {"scene": str(Path(ns.scene)), "envmaps": not ns.no_envmaps, "envmap_size": ns.envmap_size,
              "duration_s": ns.duration or 0.0, "rate": 0.0}
    plan = {"file": None, "args": {}, "nodes": {ns.id: {"node": "synthetic_rig", "params": params}}}
    meta = {"probeless.graph": {"plan": json.dumps(plan), "version": __version__, "git_revision": git_revision(),
                                "command": "probeless scene render " + " ".join(_argv(ns)), "graph_file": ""},
            "probeless.scene": {"name": scene.name, "file": str(Path(ns.scene).resolve()),
                                "yaml": scene_yaml(ns.scene)}}
    rig = Rig(scene, envmap_size=ns.envmap_size, envmaps=not ns.no_envmaps)
    seqs: dict[str, int] = defaultdict(int)
    t0 = time.monotonic()
    with BagWriter(ns.output, compression=ns.compression, force=ns.force, metadata=meta) as writer, \
            progress_bar(len(events), f"rendering {scene.name}") as tick:
        writer.write_frames(encode(f"{ns.id}/floorplan", rig.floorplan(), ns.id, 0, seq=0), log_time_ns=0)
        writer.write_frames(encode(f"{ns.id}/fisheye_from_rgbd", rig.fisheye_from_rgbd_message(), ns.id, 0, seq=0),
                            log_time_ns=0)
        for event in events:
            for output, msg in rig.messages(event):
                topic = f"{ns.id}/{output}"
                writer.write_frames(encode(topic, msg, ns.id, event.stamp_ns, seq=seqs[topic]),
                                    log_time_ns=event.stamp_ns)
                seqs[topic] += 1
            tick()
    rig.release()
    elapsed = time.monotonic() - t0
    print(f"wrote {ns.output}: {len(events)} frames, {sum(seqs.values()) + 2} messages in {elapsed:.1f} s")
    return 0


def cmd_preview(ns: argparse.Namespace) -> int:
    from probeless.scene.parse import load_scene
    from probeless.scene.preview import colorize_depth, contact_sheet, cube_net, write_png
    from probeless.scene.rig import FISHEYE_FRAME, RGBD_FRAME, FrameEvent, Rig

    scene = load_scene(ns.scene)
    if not 0 <= ns.t <= scene.duration:
        raise SceneError(f"--t {ns.t} is outside the sequence [0, {scene.duration}] s")
    objects = {o.id: o for o in scene.virtual_objects}
    if ns.object is not None and ns.object not in objects:
        raise SceneError(f"{ns.scene}: no virtual object {ns.object!r} (has: {', '.join(objects) or 'none'})")
    rig = Rig(scene, envmap_size=ns.envmap_size)
    index = int(round(ns.t * scene.rgbd.fps))
    rgb, depth, _ = rig.render_rgbd(FrameEvent(RGBD_FRAME, index, ns.t))
    fisheye, _ = rig.render_fisheye(FrameEvent(FISHEYE_FRAME, index, ns.t))
    panels = [(f"RGB  t={ns.t:.2f}s", rgb), (f"depth (0..{scene.rgbd.depth_max_m:g} m)",
                                             colorize_depth(depth, scene.rgbd.depth_max_m)),
              (f"fisheye ({scene.fisheye.model}, {scene.fisheye.fov_deg:g} deg)", fisheye)]
    if objects:
        obj = objects[ns.object] if ns.object else scene.virtual_objects[0]
        faces = rig.render_envmap(obj.position, ns.t)
        panels.append((f"ground-truth cubemap '{obj.id}' (+X -Y -X +Y; ceiling above, floor below)",
                       rig.fisheye_ldr(cube_net(faces))))
    rig.release()
    sheet = contact_sheet(panels)
    Path(ns.output).parent.mkdir(parents=True, exist_ok=True)
    write_png(ns.output, sheet)
    print(f"wrote {ns.output} ({sheet.shape[1]}x{sheet.shape[0]})")
    return 0


def cmd_compare(ns: argparse.Namespace) -> int:
    from probeless.scene.parse import load_scene
    from probeless.scene.preview import colorize_depth, contact_sheet, write_png
    from probeless.scene.rig import FISHEYE_FRAME, RGBD_FRAME, FrameEvent, Rig

    panels = []
    for path in ns.scenes:
        scene = load_scene(path)
        if not 0 <= ns.t <= scene.duration:
            raise SceneError(f"--t {ns.t} is outside {path}'s sequence [0, {scene.duration}] s")
        rig = Rig(scene, envmaps=False)
        rgb, depth, _ = rig.render_rgbd(FrameEvent(RGBD_FRAME, int(round(ns.t * scene.rgbd.fps)), ns.t))
        fisheye, _ = rig.render_fisheye(FrameEvent(FISHEYE_FRAME, int(round(ns.t * scene.fisheye.fps)), ns.t))
        rig.release()
        panels += [(f"{scene.name}: RGB t={ns.t:.2f}s", rgb),
                   (f"depth (0..{scene.rgbd.depth_max_m:g} m, black = no return)",
                    colorize_depth(depth, scene.rgbd.depth_max_m)), (f"{scene.name}: fisheye", fisheye)]
    sheet = contact_sheet(panels, cell=(400, 300), columns=3)
    Path(ns.output).parent.mkdir(parents=True, exist_ok=True)
    write_png(ns.output, sheet)
    print(f"wrote {ns.output} ({sheet.shape[1]}x{sheet.shape[0]})")
    return 0


def _argv(ns: argparse.Namespace) -> list[str]:
    out = [ns.scene, "-o", ns.output]
    if ns.duration is not None:
        out += ["--duration", str(ns.duration)]
    return out
