"""``probeless bench pbgi``: point-based GI of a virtual sphere (paper 001, §5 and §6.3): the BSH build and the
Classic / Mipmapped / Hybrid micro-buffer traversals, timed as the paper's Table 1 (BSH) and Table 3.

What is measured (one GL context; this machine runs Mesa llvmpipe on 2 shared CPU cores, not a GPU: ``device``
names the GL renderer, so the times are a CPU rasteriser's and only their ratios compare with the paper's):

* **BSH** (Table 1 analogue): :func:`~probeless.pbgi.bsh.build_bsh` with the paper's thresholds (tc 0.01,
  tn 0.98) on each scene's cloud and on 1 M points of :func:`~probeless.pbgi.bsh.synthetic_room` (best of
  ``--repeat`` builds; not with ``--quick``): seconds per stage, nodes before and after clustering. The first,
  small build that compiles (or loads) the numba kernels is timed apart (``numba_warmup_s``).
* **Table 3**: a sphere (r = 0.15 m, diffuse 0.8 grey) in each scene -- ``room``: the ``plain`` reference room
  (:func:`~probeless.pbgi.room.reference_room`, 1 cm cloud, the sphere at its object centre, seen from the room's
  ``front`` direction); ``fragment``: Open3D's scanned fragment (``SHARED_DATA/pointclouds/open3d_fragment.pcd``,
  colours sRGB), the sphere :data:`FRAGMENT_OFFSET` m from the cloud's centroid along the mean normal (towards
  where the scanner stood, in front of the scanned surfaces), seen from the side so that its lit half shows;
  image up is the scan's -y. Two views as the paper's: View1 a close-up whose silhouette spans twice the image
  (the object fills the viewport), View2 the whole object covering about a third of it. For each viewport and
  micro-buffer size, each variant's PBGI time (``ms``: ``MicroStats.seconds``, traversal and shading, GL
  finished; best of ``--repeat`` rounds, the variants interleaved in each round, after one untimed warm-up render
  per renderer; ``render_ms``: the whole render call with the G-buffer; ``cpu_ms``: that call's process CPU time
  over all llvmpipe threads, which other processes on the shared cores disturb less than wall time), the extra
  memory (``extra_mb``: peak bytes of the pair buffers, ``MicroStats.pair_bytes``; Classic has none) and the
  micro-buffer storage (``micro_mb``: every receiver's micro-buffer, 4 bytes a texel, (s x micro)² texels with
  ``--supersample`` s (default 1: the paper's micro-buffer), as one texture would hold them; the renderer fills
  them in batches of at most 64 MiB, ``micro_alloc_mb`` is the buffer it holds), in 10^6 bytes. A
  :class:`~probeless.errors.PbgiError` is recorded as ``null`` with its text (the paper's 'x').
* **Same work**: per configuration, the largest absolute difference and the relative RMS of the Mipmapped and
  Hybrid images against Classic's over the object's pixels. Gate: relative RMS <= :data:`EQUAL_REL_RMS` (the
  three compute the same cut, so the images should be identical); ``images_equal`` false fails the exit code.
* ``hybrid_speedup`` / ``mipmapped_speedup``: Classic time / that variant's time per configuration, with the
  largest and the median (``cpu``: the same of ``cpu_ms``). The reference is Classic micro-buffer PBGI
  (Ritschel et al. 2009) with the same shaders and cut (:data:`REFERENCE`).
* **Hybrid threshold** (not with ``--quick``): the Hybrid time for omega_tr = f x the micro-texel solid angle,
  f in :data:`SWEEP_FACTORS`, on room, View2, 256², 24² (the paper fixes f = 32 for its GPU): best of ``--repeat``
  rounds, each round Classic then every f, with each image checked against Classic's as above.

Time budget: ``--budget`` seconds for the whole run (default :data:`BUDGET_S`). Configurations run from the least
work (pixels x micro-texels) up; one whose predicted time (from the rate of the largest one run so far of the same
scene and view) would pass the budget is recorded as ``null``, ``"skipped: time budget ..."``. A configuration
whose first round takes over :data:`LONG_ROUND_S` s is timed once (its noise is small beside its length).
``--quick``: room, View2, 128², 16², one round, no 1 M-point build, no sweep (well under a minute).
``--figure PNG``: the Hybrid 256²/24² image of each scene and view and the times per variant as bars.
"""

from __future__ import annotations

import math
import os
import statistics
import time
from dataclasses import dataclass

import numpy as np

from probeless.bench.common import emit, log, rounded

VARIANTS = ("classic", "mipmapped", "hybrid")
SCENES = ("room", "fragment")
VIEW_MARGIN = {1: 0.5, 2: 1.535}  # silhouette diameter = image side / margin: 2x the image; ~1/3 of its area
CAMERA_DISTANCE = 1.2   # camera to sphere centre [m]
OBJECT_RADIUS = 0.15    # [m]
FRAGMENT_OFFSET = 0.45  # sphere centre from the fragment's centroid along its mean normal [m]
FRAGMENT_FILE = ("pointclouds", "open3d_fragment.pcd")
ALBEDO = (0.8, 0.8, 0.8)
EQUAL_REL_RMS = 1e-4
SWEEP_FACTORS = (1.0, 4.0, 8.0, 16.0, 32.0, 64.0)
SWEEP_CONFIG = ("room", 2, 256, 24)
FIGURE_CONFIG = (256, 24)
SYNTHETIC_POINTS = 1_000_000
BUDGET_S = 840.0
LONG_ROUND_S = 5.0
SUPERSAMPLE = 1  # the paper's micro-buffer: splatted and shaded at micro x micro texels (the renderer's default is 2)
WARMUP_SIZE = 64
REFERENCE = "Classic micro-buffer PBGI (Ritschel et al. 2009), same shaders and cut"
PAPER = {"table1": {"scene": "ATRIUM", "points": 818_000, "bsh_s": 3.62, "nodes": 1_400_000, "clusters": 430_000},
         "table3_hybrid_speedup_max": 10.0, "hybrid_factor": 32.0,
         "hardware": "Intel i7-6700 + NVIDIA GTX 1080 (paper 001, Tables 1 and 3)"}


def _ints(text: str) -> list[int]:
    """``--views`` / ``--viewports`` / ``--micro``: comma-separated positive integers."""
    import argparse

    try:
        out = [int(v) for v in str(text).split(",") if v.strip()]
    except ValueError:
        out = []
    if not out or min(out) < 1:
        raise argparse.ArgumentTypeError(f"expected comma-separated positive integers, got {text!r}")
    return out


def _scenes(text: str) -> list[str]:
    """``--scenes``: comma-separated names of :data:`SCENES`."""
    import argparse

    out = [v.strip() for v in str(text).split(",") if v.strip()]
    if not out or set(out) - set(SCENES):
        raise argparse.ArgumentTypeError(f"expected names among {', '.join(SCENES)}, got {text!r}")
    return out


def add_arguments(p) -> None:
    """``--scenes``, ``--views``, ``--viewports``, ``--micro``, ``--repeat``, ``--budget``, ``--figure``."""
    p.add_argument("--scenes", type=_scenes, default=None, help="room,fragment (default both; quick room)")
    p.add_argument("--views", type=_ints, default=None, help="1 (close-up), 2 (whole object) (default 1,2; quick 2)")
    p.add_argument("--viewports", type=_ints, default=None, help="image sides [px] (default 128,256,512; quick 128)")
    p.add_argument("--micro", type=_ints, default=None, help="micro-buffer sides (default 16,24,32; quick 16)")
    p.add_argument("--repeat", type=int, default=None, help="timed rounds, best kept (default 2; quick 1)")
    p.add_argument("--supersample", type=int, default=SUPERSAMPLE,
                   help=f"micro-buffer supersampling of the renderer (default {SUPERSAMPLE}: the paper's micro-buffer)")
    p.add_argument("--budget", type=float, default=BUDGET_S, help=f"seconds for the whole run (default {BUDGET_S:g})")
    p.add_argument("--figure", default=None, metavar="PNG", help="write the test images and the times as a PNG")


@dataclass
class Settings:
    """The run's resolved options."""

    scenes: list[str]
    views: list[int]
    viewports: list[int]
    micros: list[int]
    repeat: int
    supersample: int
    budget: float
    quick: bool
    figure: str | None


def settings(ns) -> Settings:
    """Options (lists, or comma-separated text as on the command line) with the (quick) defaults filled in;
    :class:`~probeless.errors.PbgiError` on an unknown view."""
    from probeless.errors import PbgiError

    quick = bool(ns.quick)

    def option(value, parse, default: str, quick_default: str):
        value = quick_default if value is None and quick else default if value is None else value
        return parse(value) if isinstance(value, str) else list(value)

    views = option(ns.views, _ints, "1,2", "2")
    if set(views) - set(VIEW_MARGIN):
        raise PbgiError(f"--views: expected 1 and/or 2, got {views}")
    return Settings(option(ns.scenes, _scenes, ",".join(SCENES), "room"), views,
                    option(ns.viewports, _ints, "128,256,512", "128"), option(ns.micro, _ints, "16,24,32", "16"),
                    max(1, ns.repeat or (1 if quick else 2)), int(getattr(ns, "supersample", None) or SUPERSAMPLE),
                    float(getattr(ns, "budget", None) or BUDGET_S), quick,
                    getattr(ns, "figure", None))


# -- scenes -------------------------------------------------------------------------------------------------------

@dataclass
class Scene:
    """A cloud, its BSH and where the sphere stands and is seen from."""

    name: str
    points: np.ndarray
    colors: np.ndarray
    normals: np.ndarray
    centre: np.ndarray     # sphere centre [m]
    direction: np.ndarray  # unit, from the centre towards the cameras
    up: np.ndarray         # image up
    bsh: object = None


def room_scene() -> Scene:
    """The ``plain`` reference room's 1 cm cloud; the sphere at its object centre, seen from its ``front``."""
    from probeless.pbgi.room import VIEWS, reference_room, sample_cloud

    room = reference_room("plain")
    az, el = np.radians(VIEWS["front"])
    direction = np.array([-np.sin(az) * np.cos(el), -np.cos(az) * np.cos(el), np.sin(el)])
    return Scene("room", *sample_cloud(room), np.asarray(room.object_centre, np.float64), direction,
                 np.array([0.0, 0.0, 1.0]))


def fragment_placement(points: np.ndarray, normals: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(sphere centre, camera direction, image up) in the scanned fragment: :data:`FRAGMENT_OFFSET` m from the
    centroid along the mean normal (the scanner's side), seen at right angles to that normal, scan -y up."""
    n = normals.mean(axis=0)
    n /= np.linalg.norm(n)
    down = np.array([0.0, 1.0, 0.0])
    up = (down @ n) * n - down
    up /= np.linalg.norm(up)
    centre = points.mean(axis=0) + FRAGMENT_OFFSET * n
    return centre, np.cross(n, up), up


def fragment_scene() -> Scene | str:
    """The scanned fragment (module docstring), or why it is skipped (a missing file is no error)."""
    from probeless.errors import PbgiError
    from probeless.paths import SHARED_DATA
    from probeless.pbgi.cloud import read_cloud_file

    path = SHARED_DATA.joinpath(*FRAGMENT_FILE)
    if not path.is_file():
        return f"skipped: {path} not found"
    try:
        points, colors, normals = read_cloud_file(path)
    except PbgiError as exc:
        return f"skipped: {exc}"
    if normals is None:
        return f"skipped: {path} has no normals"
    points, normals = points.astype(np.float64), normals.astype(np.float64)
    return Scene("fragment", points, colors, normals, *fragment_placement(points, normals))


def camera(scene: Scene, view: int, size: int) -> tuple[np.ndarray, np.ndarray]:
    """(K, world_from_camera) of a ``size``² pinhole at :data:`CAMERA_DISTANCE` framing the sphere for ``view``."""
    from probeless.coarse.view import look_at

    half = math.asin(OBJECT_RADIUS / CAMERA_DISTANCE)
    f = size / 2 / (math.tan(half) * VIEW_MARGIN[view])
    c = (size - 1) / 2
    K = np.array([[f, 0.0, c], [0.0, f, c], [0.0, 0.0, 1.0]])
    return K, look_at(scene.centre + CAMERA_DISTANCE * scene.direction, scene.centre, up=scene.up)


# -- BSH (Table 1) ---------------------------------------------------------------------------------------------------

def bsh_row(name: str, report) -> dict:
    """One row of the BSH table from a :class:`~probeless.pbgi.bsh.BshReport`."""
    return {"cloud": name, "points": report.n_points, "leaves": report.n_leaves, "nodes": report.n_nodes,
            "nodes_clustered": report.n_nodes_pruned, "clusters": report.n_clusters, "voxel_m": report.voxel,
            "build_s": report.total, "stages_s": dict(report.times)}


def build_scene_bsh(scene: Scene, repeat: int) -> dict:
    """Best of ``repeat`` builds of the scene's BSH (kept on the scene); its row."""
    from probeless.pbgi.bsh import build_bsh

    best = None
    for _ in range(repeat):
        bsh = build_bsh(scene.points, scene.colors, scene.normals)
        if best is None or bsh.report.total < best.report.total:
            best = bsh
    scene.bsh = best
    return bsh_row(scene.name, best.report)


def numba_warmup() -> float:
    """Seconds of a first small build (numba compiles the kernels or loads them from its cache)."""
    from probeless.pbgi.bsh import build_bsh, synthetic_room

    t0 = time.perf_counter()
    build_bsh(*synthetic_room(2000, 1))
    return time.perf_counter() - t0


def synthetic_row(repeat: int) -> dict:
    """BSH row of :data:`SYNTHETIC_POINTS` points of ``synthetic_room`` (best of ``repeat``)."""
    from probeless.pbgi.bsh import time_build

    return bsh_row(f"synthetic_room {SYNTHETIC_POINTS // 1_000_000}M", time_build(SYNTHETIC_POINTS, repeat=repeat))


# -- rendering -------------------------------------------------------------------------------------------------------

class Renderers:
    """One :class:`~probeless.pbgi.render.PbgiRenderer` per (scene, micro, hybrid factor) on a shared context, each
    warmed up by one untimed render when made."""

    def __init__(self, supersample: int = SUPERSAMPLE):
        from probeless.gl.context import create_context

        self.supersample = supersample
        self.ctx = create_context()
        self.device = self.ctx.info["GL_RENDERER"]
        self.made: dict[tuple, object] = {}

    def get(self, scene: Scene, micro: int, factor: float = 32.0):
        key = (scene.name, micro, factor)
        if key not in self.made:
            from probeless.ibl.mesh_io import place, uv_sphere
            from probeless.pbgi.materials import Brdf
            from probeless.pbgi.render import PbgiObject, PbgiRenderer

            mesh = place(*uv_sphere(1.0, 48, 96), scene.centre, radius=OBJECT_RADIUS)
            r = PbgiRenderer([PbgiObject("sphere", mesh, Brdf("lambert", ALBEDO, 1.0))], variant="hybrid",
                             micro=micro, hybrid_factor=factor, supersample=self.supersample, ctx=self.ctx)
            r.set_cloud(scene.bsh)
            r.render(*camera(scene, 2, WARMUP_SIZE), WARMUP_SIZE, WARMUP_SIZE)
            self.made[key] = r
        return self.made[key]

    def release(self) -> None:
        for r in self.made.values():
            r.release()
        self.ctx.release()


def render_once(renderer, cam, size: int, variant: str) -> tuple[dict, object]:
    """(figures, PbgiResult or None) of one render; a PbgiError becomes ``{"error": text}``."""
    from probeless.errors import PbgiError

    t0, c0 = time.perf_counter(), time.process_time()
    try:
        out = renderer.render(*cam, size, size, variant=variant)
    except PbgiError as exc:
        return {"error": str(exc)}, None
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    s = out.stats
    return {"ms": s.seconds * 1e3, "render_ms": wall * 1e3, "cpu_ms": cpu * 1e3, "shade_ms": s.shade_seconds * 1e3,
            "extra_mb": s.pair_bytes / 1e6, "micro_mb": s.pixels * renderer.micro.side ** 2 * 4 / 1e6,
            "micro_alloc_mb": s.micro_bytes / 1e6, "batches": s.batches,
            "iterations": s.iterations, "pairs": s.pairs, "classic_pairs": s.classic_pairs,
            "classic_dispatches": s.classic_dispatches}, out


def image_difference(ref, img, mask: np.ndarray) -> dict:
    """Largest absolute difference and relative RMS of ``img`` against ``ref`` over ``mask``."""
    a, b = img.color[mask].astype(np.float64), ref.color[mask].astype(np.float64)
    if not mask.any() or not np.array_equal(img.mask, ref.mask):
        return {"max_abs_diff": None, "rel_rms": None, "equal": False}
    rms = math.sqrt(float(np.mean((a - b) ** 2)))
    norm = math.sqrt(float(np.mean(b ** 2)))
    rel = rms / norm if norm > 0 else (0.0 if rms == 0 else math.inf)
    return {"max_abs_diff": float(np.abs(a - b).max()), "rel_rms": rel, "equal": bool(rel <= EQUAL_REL_RMS)}


def time_jobs(jobs: dict, cam, size: int, repeat: int, long_s: float = LONG_ROUND_S) -> tuple[dict, dict, int]:
    """Time ``jobs`` {label: (renderer, variant)} in rounds that interleave them. Returns ({label: figures of its
    best run, with ``runs_ms``}, {label: first image}, rounds run). A round over ``long_s`` s is not repeated; a
    failed job is not retried."""
    best: dict = {}
    images: dict = {}
    runs: dict = {k: [] for k in jobs}
    rounds = 0
    for _ in range(repeat):
        t0 = time.perf_counter()
        for k, (renderer, variant) in jobs.items():
            if "error" in best.get(k, {}):
                continue
            fig, out = render_once(renderer, cam, size, variant)
            if out is None:
                best.setdefault(k, fig)
                continue
            images.setdefault(k, out)
            runs[k].append(fig["ms"])
            if k not in best or fig["ms"] < best[k]["ms"]:
                best[k] = fig
        rounds += 1
        if time.perf_counter() - t0 > long_s:
            break
    for k, fig in best.items():
        if "ms" in fig:
            fig["runs_ms"] = runs[k]
    return best, images, rounds


def compare_variants(figs: dict, images: dict) -> dict:
    """Same-work figures and speedups of one configuration (in place into ``figs``' variants)."""
    out = {"object_pixels": None, "equal": True}
    ref = images.get("classic")
    if ref is not None:
        out["object_pixels"] = int(ref.mask.sum())
    for v in ("mipmapped", "hybrid"):
        if v not in figs:
            continue
        if ref is not None and v in images:
            figs[v].update(image_difference(ref, images[v], ref.mask))
            out["equal"] &= figs[v]["equal"]
        for key, suffix in (("ms", ""), ("cpu_ms", "_cpu")):
            c, t = figs.get("classic", {}).get(key), figs[v].get(key)
            out[f"{v}_speedup{suffix}"] = c / t if c and t else None
    return out


def null_config(variants, reason: str) -> dict:
    """A configuration that did not run: every variant null with ``reason``."""
    return {"variants": {v: {"ms": None, "error": reason} for v in variants}, "skipped": reason, "equal": True}


# -- Table 3 ---------------------------------------------------------------------------------------------------------

def plan(st: Settings, scenes: dict) -> list[tuple[str, int, int, int]]:
    """(scene, view, viewport, micro) from the least work up (View2 before View1 at equal work)."""
    todo = [(s, v, n, m) for s in st.scenes if isinstance(scenes.get(s), Scene)
            for v in st.views for n in st.viewports for m in st.micros]
    return sorted(todo, key=lambda c: (c[2] ** 2 * c[3] ** 2, -c[1], SCENES.index(c[0])))


class Budget:
    """Predicts a configuration's seconds from the rate (seconds per pixel x micro-texel) of the largest
    configuration run so far of the same scene and view, and says whether it still fits."""

    def __init__(self, seconds: float, start: float):
        self.seconds, self.start = float(seconds), start
        self.rates: dict[tuple, tuple[float, float, int]] = {}  # (scene, view) -> (work, s/work per round, rounds)

    def predict(self, key, work: float, repeat: int) -> float | None:
        if key not in self.rates:
            return None
        _, rate, _ = self.rates[key]
        one = rate * work
        return one * (1 if one > LONG_ROUND_S else repeat)

    def fits(self, key, work: float, repeat: int) -> tuple[bool, str]:
        left = self.seconds - (time.perf_counter() - self.start)
        pred = self.predict(key, work, repeat)
        if pred is not None and pred > left:
            return False, f"skipped: time budget (predicted {pred:.0f} s, {max(left, 0):.0f} s of --budget left)"
        return True, ""

    def record(self, key, work: float, seconds: float, rounds: int) -> None:
        if key not in self.rates or work >= self.rates[key][0]:
            self.rates[key] = (work, seconds / max(rounds, 1) / work, rounds)


def run_config(renderers: Renderers, scene: Scene, view: int, size: int, micro: int, repeat: int) -> tuple:
    """(row, hybrid image or None, rounds) of one configuration."""
    from probeless.errors import PbgiError

    try:
        r = renderers.get(scene, micro)
    except PbgiError as exc:
        return null_config(VARIANTS, f"error: {exc}"), None, 0
    figs, images, rounds = time_jobs({v: (r, v) for v in VARIANTS}, camera(scene, view, size), size, repeat)
    row = {"variants": figs, **compare_variants(figs, images), "rounds": rounds}
    return row, images.get("hybrid"), rounds


def table3(st: Settings, scenes: dict, renderers: Renderers, budget: Budget) -> tuple[list, dict]:
    """Every configuration of :func:`plan` (rows in plan order) and the Hybrid images at :data:`FIGURE_CONFIG`."""
    from probeless.progress import progress

    rows, figure_images = [], {}
    todo = plan(st, scenes)
    with progress(len(todo), "pbgi Table 3", transient=True) as tick:
        for name, view, size, micro in todo:
            key, work = (name, view), float(size * size * micro * micro)
            ok, reason = budget.fits(key, work, st.repeat)
            head = {"scene": name, "view": view, "viewport": size, "micro": micro}
            if not ok:
                log(f"{name} View{view} {size}^2 micro {micro}^2: {reason}")
                rows.append({**head, **null_config(VARIANTS, reason)})
                tick()
                continue
            t0 = time.perf_counter()
            row, hybrid, rounds = run_config(renderers, scenes[name], view, size, micro, st.repeat)
            seconds = time.perf_counter() - t0
            if rounds:
                budget.record(key, work, seconds, rounds)
            if hybrid is not None and (size, micro) == FIGURE_CONFIG:
                figure_images[key] = hybrid
            rows.append({**head, **row, "seconds": seconds})
            log(f"{name} View{view} {size}^2 micro {micro}^2: " + ", ".join(
                f"{v} {row['variants'][v]['ms']:.0f} ms" if row["variants"][v].get("ms") else f"{v} x"
                for v in VARIANTS) + f" ({seconds:.0f} s)")
            tick()
    return rows, figure_images


def speedup_summary(rows: list) -> dict:
    """Per variant: the max and median over the configurations of its speedup over Classic (PBGI wall time), and
    the same of the process CPU time (``cpu``: less sensitive to other processes on the shared cores)."""
    out = {}
    for v in ("hybrid", "mipmapped"):
        out[v] = {}
        for suffix, into in (("", out[v]), ("_cpu", out[v].setdefault("cpu", {}))):
            vals = [r[f"{v}_speedup{suffix}"] for r in rows if r.get(f"{v}_speedup{suffix}")]
            into.update({"max": max(vals) if vals else None,
                         "median": statistics.median(vals) if vals else None, "configs": len(vals)})
    return out


# -- hybrid threshold sweep ------------------------------------------------------------------------------------------

def sweep(st: Settings, scenes: dict, renderers: Renderers) -> dict | None:
    """Hybrid time per omega_tr factor at :data:`SWEEP_CONFIG` (the first scene there when room is not run)."""
    name, view, size, micro = SWEEP_CONFIG
    if name not in scenes or not isinstance(scenes[name], Scene):
        name = next((s for s in st.scenes if isinstance(scenes.get(s), Scene)), None)
        if name is None:
            return None
    scene, cam = scenes[name], camera(scenes[name], view, size)
    jobs = {"classic": (renderers.get(scene, micro), "classic")}
    jobs.update({f: (renderers.get(scene, micro, f), "hybrid") for f in SWEEP_FACTORS})
    figs, images, _ = time_jobs(jobs, cam, size, st.repeat, long_s=math.inf)
    ref = images.get("classic")
    points = []
    for f in SWEEP_FACTORS:
        row = {"factor": f, **figs[f]}
        if ref is not None and f in images:
            row.update(image_difference(ref, images[f], ref.mask))
        points.append(row)
        log(f"sweep omega_tr = {f:g} omega: " + (f"{row['ms']:.0f} ms" if row.get("ms") else "x"))
    timed = [p for p in points if p.get("ms")]
    fastest = min(timed, key=lambda p: p["ms"])["factor"] if timed else None
    return {"scene": name, "view": view, "viewport": size, "micro": micro, "classic_ms": figs["classic"].get("ms"),
            "points": points, "fastest_factor": fastest, "paper_factor": PAPER["hybrid_factor"],
            "equal": all(p.get("equal", False) for p in timed)}


# -- figure ----------------------------------------------------------------------------------------------------------

def write_figure(path: str, images: dict, rows: list) -> None:
    """The Hybrid images (one per scene and view) above bars of each variant's time per configuration."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from probeless.color import to_srgb8
    from probeless.pbgi.cli import _auto_exposure

    keys = sorted(images)
    timed = sorted((r for r in rows if not r.get("skipped")),
                   key=lambda r: (SCENES.index(r["scene"]), r["view"], r["viewport"], r["micro"]))
    fig = plt.figure(figsize=(max(8, 2.6 * len(keys)), 7.5))
    grid = fig.add_gridspec(2, max(len(keys), 1), height_ratios=(1, 1.2))
    for i, key in enumerate(keys):
        out = images[key]
        ax = fig.add_subplot(grid[0, i])
        ax.imshow(to_srgb8(out.color * _auto_exposure(out.color, out.mask)))
        ax.set_title(f"{key[0]} View{key[1]} (Hybrid {FIGURE_CONFIG[0]}², {FIGURE_CONFIG[1]}²)", fontsize=8)
        ax.axis("off")
    ax = fig.add_subplot(grid[1, :])
    x = np.arange(len(timed))
    for j, v in enumerate(VARIANTS):
        ms = [r["variants"][v].get("ms") or 0.0 for r in timed]
        ax.bar(x + (j - 1) * 0.27, ms, 0.27, label=v)
    ax.set_xticks(x, [f"{r['scene'][:4]} V{r['view']} {r['viewport']}/{r['micro']}" for r in timed], fontsize=6,
                  rotation=90)
    ax.set_yscale("log")
    ax.set_ylabel("PBGI time [ms] (llvmpipe, 2 cores)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, axis="y")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def missing_figure_images(st: Settings, scenes: dict, renderers: Renderers, images: dict) -> None:
    """Render the figure's Hybrid images that the table did not (a reduced grid, or a skipped configuration)."""
    size, micro = FIGURE_CONFIG
    for name in st.scenes:
        for view in st.views:
            if isinstance(scenes.get(name), Scene) and (name, view) not in images:
                _, out = render_once(renderers.get(scenes[name], micro), camera(scenes[name], view, size), size,
                                     "hybrid")
                if out is not None:
                    images[(name, view)] = out


# -- run -------------------------------------------------------------------------------------------------------------

def load_scenes(st: Settings) -> dict:
    """{name: Scene or the reason it is skipped}, BSHs not built yet."""
    out = {}
    for name in st.scenes:
        log(f"loading {name}")
        out[name] = room_scene() if name == "room" else fragment_scene()
    return out


def bsh_table(st: Settings, scenes: dict) -> dict:
    """Numba warm-up, then each scene's BSH (kept for rendering) and the 1 M-point build (not quick)."""
    from probeless.pbgi.bsh import MAX_CLUSTER_RADIUS

    warm = numba_warmup()
    rows = []
    for name, scene in scenes.items():
        log(f"BSH of {name}")
        rows.append(build_scene_bsh(scene, st.repeat) if isinstance(scene, Scene) else {"cloud": name,
                                                                                        "skipped": scene})
    if not st.quick:
        log(f"BSH of {SYNTHETIC_POINTS} synthetic points")
        rows.append(synthetic_row(st.repeat))
    return {"numba_warmup_s": warm, "tc": 0.01, "tn": 0.98, "max_cluster_radius_m": MAX_CLUSTER_RADIUS, "rows": rows}


def scene_info(scenes: dict) -> dict:
    """Where the sphere is in each scene (or why the scene is skipped)."""
    return {name: ({"points": len(s.points), "sphere_centre": s.centre, "sphere_radius": OBJECT_RADIUS,
                    "camera_direction": s.direction, "up": s.up} if isinstance(s, Scene) else {"skipped": s})
            for name, s in scenes.items()}


def measure(st: Settings) -> dict:
    """The whole benchmark as one result object (see the module docstring)."""
    start = time.perf_counter()
    scenes = load_scenes(st)
    bsh = bsh_table(st, scenes)
    renderers = Renderers(st.supersample)
    try:
        sweep_result = None if st.quick else sweep(st, scenes, renderers)
        rows, images = table3(st, scenes, renderers, Budget(st.budget, start))
        if st.figure:
            missing_figure_images(st, scenes, renderers, images)
            write_figure(st.figure, images, rows)
        device = renderers.device
    finally:
        renderers.release()
    equal = all(r["equal"] for r in rows) and (sweep_result is None or sweep_result["equal"])
    speed = speedup_summary(rows)
    return {"benchmark": "pbgi", "reference": REFERENCE, "paper": PAPER, "device": device,
            "cpu_cores": os.cpu_count(), "quick": st.quick,
            "settings": {"scenes": st.scenes, "views": st.views, "viewports": st.viewports, "micro": st.micros,
                         "repeat": st.repeat, "supersample": st.supersample, "budget_s": st.budget,
                         "view_margin": VIEW_MARGIN, "albedo": ALBEDO, "gate_rel_rms": EQUAL_REL_RMS},
            "scenes": scene_info(scenes), "bsh": bsh, "table3": rows,
            "images_equal": bool(equal), "hybrid_speedup": speed["hybrid"], "mipmapped_speedup": speed["mipmapped"],
            "configs_run": sum(not r.get("skipped") for r in rows), "configs_skipped": sum(
                bool(r.get("skipped")) for r in rows),
            "hybrid_threshold_sweep": sweep_result, "figure": st.figure, "duration_s": time.perf_counter() - start}


# -- output ----------------------------------------------------------------------------------------------------------

def _cell(fig: dict | None, key: str, fmt: str) -> str:
    v = (fig or {}).get(key)
    return "x" if v is None else format(v, fmt)


def _grid_table(r: dict, title: str, variants, key: str, fmt: str):
    """Rows variant x viewport, columns scene/view x micro (the paper's Table 3 layout)."""
    from rich.markup import escape
    from rich.table import Table

    s = r["settings"]
    cols = [(sc, v) for sc in s["scenes"] for v in s["views"]]
    cells = {(x["scene"], x["view"], x["viewport"], x["micro"]): x for x in r["table3"]}
    t = Table(title=escape(title))
    t.add_column("variant")
    t.add_column("viewport", justify="right")
    for sc, v in cols:
        for m in s["micro"]:
            t.add_column(f"{sc} V{v}\n{m}x{m}", justify="right")
    for var in variants:
        for n in s["viewports"]:
            row = [var if n == s["viewports"][0] else "", f"{n}x{n}"]
            for sc, v in cols:
                for m in s["micro"]:
                    row.append(_cell(cells.get((sc, v, n, m), {}).get("variants", {}).get(var), key, fmt))
            t.add_row(*row)
    return t


def print_table(r: dict) -> None:
    """The BSH table, Table 3 (time, extra memory, micro-buffer storage), the same-work gate, the sweep."""
    import sys

    from rich.console import Console
    from rich.table import Table

    console = Console(file=sys.stdout)
    if not console.is_terminal:
        console = Console(file=sys.stdout, width=200)
    b = r["bsh"]
    t = Table(title=f"BSH build (tc {b['tc']}, tn {b['tn']}; numba warm-up {b['numba_warmup_s']:.1f} s)")
    for c in ("cloud", "points", "nodes", "clustered nodes", "clusters", "build s"):
        t.add_column(c, justify="left" if c == "cloud" else "right")
    for row in b["rows"]:
        if "skipped" in row:
            t.add_row(row["cloud"], row["skipped"], "", "", "", "")
        else:
            t.add_row(row["cloud"], f"{row['points']:,}", f"{row['nodes']:,}", f"{row['nodes_clustered']:,}",
                      f"{row['clusters']:,}", f"{row['build_s']:.2f}")
    console.print(t)
    console.print(_grid_table(r, f"PBGI time [ms] on {r['device']} ({r['cpu_cores']} cores); x = error or skipped",
                              VARIANTS, "ms", ".1f"))
    console.print(_grid_table(r, "extra memory [MB] (pair buffers)", ("mipmapped", "hybrid"), "extra_mb", ".1f"))
    console.print(_grid_table(r, "micro-buffer storage [MB]", ("classic",), "micro_mb", ".1f"))
    h, m = r["hybrid_speedup"], r["mipmapped_speedup"]
    console.print(f"reference: {r['reference']}; images_equal={r['images_equal']} (gate rel RMS <= "
                  f"{r['settings']['gate_rel_rms']:g}); hybrid speedup max {_cell(h, 'max', '.2f')} median "
                  f"{_cell(h, 'median', '.2f')}; mipmapped speedup max {_cell(m, 'max', '.2f')} median "
                  f"{_cell(m, 'median', '.2f')} (by CPU time: hybrid max {_cell(h['cpu'], 'max', '.2f')} median "
                  f"{_cell(h['cpu'], 'median', '.2f')}); {r['configs_run']} configurations run, {r['configs_skipped']} "
                  f"skipped; {r['duration_s']:.0f} s")
    sw = r["hybrid_threshold_sweep"]
    if sw:
        console.print(f"Hybrid threshold ({sw['scene']} View{sw['view']} {sw['viewport']}², {sw['micro']}²; classic "
                      f"{_cell(sw, 'classic_ms', '.0f')} ms): " + ", ".join(
                          f"{p['factor']:g} omega {_cell(p, 'ms', '.0f')} ms" for p in sw["points"])
                      + f"; fastest {sw['fastest_factor']} (paper {sw['paper_factor']:g})")


def run(ns) -> int:
    """Run the benchmark; exit 1 when the variants' images differ (the figures are printed first)."""
    result = rounded(measure(settings(ns)), 6)
    emit(result, ns.json, print_table)
    return 0 if result["images_equal"] else 1


def main(json_out: bool = False, quick: bool = False) -> int:
    """``run`` with the defaults (the benchmark interface of :mod:`probeless.bench`)."""
    import argparse

    return run(argparse.Namespace(json=json_out, quick=quick, scenes=None, views=None, viewports=None, micro=None,
                                  repeat=None, supersample=SUPERSAMPLE, budget=BUDGET_S, figure=None))


if __name__ == "__main__":
    from probeless.bench.common import module_main

    raise SystemExit(module_main(__name__))
