"""``probeless eval envmap --graph GRAPH SCENE_OR_BAG``: score the shipped graph's environment maps.

What ships is scored, not a re-implementation: the graph (``launch/probeless.yaml`` by default) runs as
``probeless launch`` runs it, on a ``probeless scene render`` recording replayed in lockstep (``source:=recording
rate:=0``: every message waits for the graph, so no frame is dropped and a run is reproducible), with the
poses from its SLAM, its pose interpolation, the calibration and floorplan the recording *gives* (a
``*_realistic`` scene's perturbed ones), and its own Δ handling. Each method is one run with one ``node:``
swap (``envmap_node:=cubemap_renderer`` for ``ours``, ``baseline_envmap`` for ``baseline``); its ``envmap/envmaps``
topic is recorded and every map is scored against the recording's truth for the same fisheye frame
(``rig/gt/envmap/<id>``, linear HDR, and ``rig/gt/envmap_ldr/<id>``, the fisheye's LDR units at that moment) with
:func:`probeless.envmap.score.score_envmap`, on the texels both methods observed (``Cubemap.observed``).
Linear (HDR) maps (``lighting:=hdr``, which ``photo:=FILE`` selects) are scored with the same scores, as linear
(``score_envmap(..., linear=True)``): unclipped for the HDR ones, as the camera would clip them for the LDR ones.

With ``lightings`` (``--graph-lighting ldr hdr``) each method runs once per lighting mode (``lighting:=NAME``),
and every run is scored on the texels all of them observed, so LDR and HDR lighting compare on the same texels in
one table.

A scene file is rendered first (cached under ``out/cache/eval_envmap`` by the scene file's content, the
duration and the truth size).
"""

from __future__ import annotations

import hashlib
import subprocess
import sys
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from probeless.errors import BagError, ProbelessError
from probeless.paths import REPO_ROOT

GRAPH_METHODS = {"ours": "cubemap_renderer", "baseline": "baseline_envmap"}
CACHE = Path("out/cache/eval_envmap")


@dataclass
class Truth:
    """The recording's truth per fisheye frame, keyed by the fisheye clock's stamp."""

    hdr: dict[tuple[str, int], np.ndarray] = field(default_factory=dict)   # (object, stamp) -> linear (6, S, S, 3)
    ldr: dict[tuple[str, int], np.ndarray] = field(default_factory=dict)   # (object, stamp) -> camera LDR 0..1
    exposure: dict[int, np.ndarray] = field(default_factory=dict)          # stamp -> (3,) gains [-]
    start_ns: int = 0


@dataclass
class GraphRun:
    """One method's maps: (object, stamp) -> (faces, observed mask or None); faces are camera LDR 0..1, or with
    ``linear`` camera linear units (radiance x exposure, 1 = LDR white, unclipped: ``lighting:=hdr``)."""

    method: str
    maps: dict[tuple[str, int], tuple[np.ndarray, np.ndarray | None]]
    log: Path
    linear: bool = False


def render_recording(scene: str, duration: float | None, envmap_size: int, show_progress: bool,
                     cache: Path = CACHE) -> Path:
    """The scene's ``probeless scene render`` recording (with truth maps), rendered once and cached in ``cache``."""
    from probeless.scene.extends import scene_yaml

    text = scene_yaml(scene)
    key = hashlib.sha256(f"{text}|{duration}|{envmap_size}".encode()).hexdigest()[:16]
    out = Path(cache) / f"{Path(scene).stem}_{key}.mcap"
    if out.is_file():
        return out
    out.parent.mkdir(parents=True, exist_ok=True)
    cmd = [sys.executable, "-m", "probeless", "scene", "render", scene, "-o", str(out), "--force",
           "--envmap-size", str(envmap_size)] + ([] if duration is None else ["--duration", str(duration)])
    _run(cmd, out.with_suffix(".log"), show_progress)
    return out


def _run(cmd: list[str], log: Path, show_output: bool) -> None:
    log.parent.mkdir(parents=True, exist_ok=True)
    with open(log, "w", encoding="utf-8") as f:
        proc = subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT, cwd=Path.cwd())
    if proc.returncode != 0:
        tail = "\n".join(log.read_text(errors="replace").splitlines()[-15:])
        raise ProbelessError(f"`{' '.join(cmd)}` failed (exit {proc.returncode}); log {log}:\n{tail}")


def run_label(method: str, lighting: str | None) -> str:
    """A run's name in the results: the method, with ``[lighting]`` when runs compare lighting modes."""
    return method if lighting is None else f"{method}[{lighting}]"


def run_graph(graph: str, recording: Path, objects: str, method: str, out_dir: Path, args: list[str],
              show_progress: bool, record: tuple[str, ...] = (), lighting: str | None = None) -> GraphRun:
    """Launch ``graph`` in lockstep on ``recording`` with ``method``'s envmap node (and ``lighting:=lighting`` when
    given); read back its maps. The run's ``maps.mcap`` also records the topics in ``record`` (e.g.
    ``slam/model/points``)."""
    label = run_label(method, lighting)
    run_dir = out_dir / label.replace("[", "_").replace("]", "")
    maps = run_dir / "maps.mcap"
    extra = [] if lighting is None else [f"lighting:={lighting}"]
    cmd = [sys.executable, "-m", "probeless", "launch", graph, "source:=recording", f"bag:={recording}", "rate:=0",
           f"objects:={objects}", f"envmap_node:={GRAPH_METHODS[method]}", f"out_dir:={run_dir}", *args, *extra,
           "--record", str(maps), "--record-topics", "envmap/envmaps", *record, "--force"]
    _run(cmd, run_dir / "launch.log", show_progress)
    found, linear = read_maps(maps)
    return GraphRun(label, found, run_dir / "launch.log", linear)


def read_maps(path: Path) -> tuple[dict[tuple[str, int], tuple[np.ndarray, np.ndarray | None]], bool]:
    """((object, stamp) -> (faces float32, observed (6, S, S) or None), linear) of a recorded envmaps topic: faces
    camera LDR 0..1, or camera linear units when the maps are linear (HDR); a run's maps are all one or the other."""
    from probeless.bag.reader import BagReader

    out, kinds = {}, set()
    with BagReader(path) as reader:
        for m in reader.messages(["envmap/envmaps"]):
            cube = reader.decode(m)
            kinds.add(bool(cube.linear))
            faces = cube.faces[..., :3]
            faces = faces.astype(np.float32) / 255.0 if faces.dtype == np.uint8 else faces.astype(np.float32)
            out[cube.object_id, cube.header.stamp_ns] = (faces, cube.observed if len(cube.observed) else None)
    if not out:
        raise ProbelessError(f"{path}: the graph published no environment map (see the launch log next to it)")
    if len(kinds) > 1:
        raise ProbelessError(f"{path}: the run published both linear (HDR) and LDR maps on envmap/envmaps")
    return out, kinds.pop()


def read_truth(recording: Path) -> Truth:
    """The recording's true maps and fisheye gains, keyed by the fisheye frame's stamp (its own clock)."""
    from probeless.bag.reader import BagReader

    truth = Truth()
    true_stamps: dict[str, list[tuple[int, Any]]] = defaultdict(list)
    gains: list[tuple[int, np.ndarray]] = []
    with BagReader(recording) as reader:
        truth.start_ns = reader.start_ns or 0
        wanted = [t for t in reader.topics() if t.startswith(("rig/gt/envmap/", "rig/gt/envmap_ldr/"))
                  or t == "rig/gt/fisheye_exposure"]  # not the images: their chunks need not be read
        for m in reader.messages(wanted):
            if m.topic.startswith(("rig/gt/envmap/", "rig/gt/envmap_ldr/")):
                true_stamps[m.topic].append((m.log_time_ns, reader.decode(m)))
            elif m.topic == "rig/gt/fisheye_exposure":
                msg = reader.decode(m)
                gains.append((msg.header.stamp_ns, np.asarray(msg.data, np.float64).reshape(3)))
    if not true_stamps:
        raise BagError(f"{recording}: no rig/gt/envmap/* topics (render it without --no-envmaps)")
    if not gains:
        raise BagError(f"{recording}: no rig/gt/fisheye_exposure topic (re-render it with this version)")
    for topic, msgs in true_stamps.items():
        if len(msgs) != len(gains):
            raise BagError(f"{recording}: {len(msgs)} {topic} messages but {len(gains)} fisheye frames")
        for (stamp, exposure), (_, cube) in zip(sorted(gains, key=lambda g: g[0]), sorted(msgs, key=lambda x: x[0])):
            truth.exposure[stamp] = exposure
            if topic.startswith("rig/gt/envmap_ldr/"):
                truth.ldr[cube.object_id, stamp] = cube.faces[..., :3].astype(np.float32) / 255.0
            else:
                truth.hdr[cube.object_id, stamp] = cube.faces[..., :3].astype(np.float32)
    return truth


def graph_path(graph: str) -> str:
    """``graph`` as given, or relative to the repository when it is not a file here (``launch/probeless.yaml``)."""
    p = Path(graph)
    if p.is_file():
        return str(p)
    if (REPO_ROOT / p).is_file():
        return str(REPO_ROOT / p)
    raise ProbelessError(f"--graph {graph}: file not found")


def score_runs(runs: dict[str, GraphRun], truth: Truth) -> dict[str, dict[str, dict[str, Any]]]:
    """method -> object -> {score: mean, "series": {score: [...]}, "times_s": [...]}: every map whose fisheye frame
    has a truth and that every method published, scored on the texels all methods observed."""
    from probeless.envmap.score import SCORES, score_envmap

    keys = sorted(set.intersection(*(set(r.maps) for r in runs.values())) & set(truth.ldr), key=lambda k: (k[1], k[0]))
    if not keys:
        raise ProbelessError("no map stamp is shared by every method and the truth: nothing to score")
    out: dict[str, dict[str, dict[str, Any]]] = {m: {} for m in runs}
    for oid, stamp in keys:
        size = truth.ldr[oid, stamp].shape[1]
        masks = [_down(r.maps[oid, stamp][1], size) for r in runs.values()]
        common = np.logical_and.reduce([m for m in masks if m is not None]) if any(m is not None for m in masks) \
            else None
        for method, run in runs.items():
            faces, observed = run.maps[oid, stamp]
            scores = score_envmap(faces, truth.ldr[oid, stamp], truth.hdr[oid, stamp], exposure=truth.exposure[stamp],
                                  observed=_down(observed, size), common=common, linear=run.linear)
            entry = out[method].setdefault(oid, {"series": {k: [] for k in SCORES}, "times_s": []})
            for k in SCORES:
                entry["series"][k].append(scores[k])
            entry["times_s"].append((stamp - truth.start_ns) / 1e9)
    for per_object in out.values():
        for entry in per_object.values():
            for k, values in entry["series"].items():
                entry[k] = float(np.nanmean(values)) if np.isfinite(values).any() else float("nan")
    return out


def _down(mask: np.ndarray | None, size: int) -> np.ndarray | None:
    """A texel of the ``size`` map counts as observed when every texel of ``mask`` it covers is."""
    if mask is None:
        return None
    k = mask.shape[1] // size
    if k * size != mask.shape[1]:
        raise ProbelessError(f"observed mask of {mask.shape[1]} texels is not a multiple of the truth's {size}")
    return mask.reshape(6, size, k, size, k).all(axis=(2, 4))


def evaluate_graph(source: str, *, graph: str, methods: list[str], duration: float | None, envmap_size: int,
                   out_dir: Path, graph_args: list[str], show_progress: bool, cache: Path = CACHE,
                   record: tuple[str, ...] = (), lightings: list[str] | None = None) -> dict[str, Any]:
    """Render (a scene) or take (a recording), run the graph once per method (and per lighting mode of
    ``lightings``: runs ``ours[ldr]``, ``ours[hdr]``, ...), score every run on the texels all runs observed
    (module doc)."""
    from probeless.eval.envmap import scene_path
    from probeless.progress import progress

    graph = graph_path(graph)
    scene = scene_path(source)
    recording = Path(source) if Path(source).suffix == ".mcap" else render_recording(source, duration, envmap_size,
                                                                                      show_progress, cache)
    if lightings is not None and (not lightings or len(set(lightings)) != len(lightings)):
        raise ProbelessError(f"--graph-lighting needs distinct lighting modes, got {lightings}")
    if lightings is not None and any(a.startswith("lighting:=") for a in graph_args):
        raise ProbelessError("give the lighting modes with --graph-lighting or --graph-arg lighting:=, not both")
    plan = [(m, li) for m in methods for li in (lightings or [None])]
    runs = {}
    with progress(len(plan), f"graph runs on {Path(source).name}", enabled=show_progress) as tick:
        for method, lighting in plan:
            run = run_graph(graph, recording, scene, method, out_dir, graph_args, show_progress, record, lighting)
            runs[run.method] = run
            tick()
    scores = score_runs(runs, read_truth(recording))
    result: dict[str, Any] = {"mode": "graph", "graph": graph, "scene": scene, "recording": str(recording),
                              "graph_args": graph_args, "units": "camera LDR (PSNR peak 1); HDR scores vs gt/envmap",
                              "linear_maps": {m: r.linear for m, r in runs.items()}, "methods": scores}
    if "ours" in scores and "baseline" in scores:
        result["ours_minus_baseline"] = {
            o: {k: scores["ours"][o][k] - scores["baseline"][o][k] for k in ("psnr_common", "psnr_all")}
            | {"sh_diffuse_error_ratio": scores["ours"][o]["sh_diffuse_error_ldr"]
               / max(scores["baseline"][o]["sh_diffuse_error_ldr"], 1e-12)}
            for o in scores["ours"]}
    return result
