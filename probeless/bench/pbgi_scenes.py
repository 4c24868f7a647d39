"""The scenes, cameras and renderers of ``probeless bench pbgi`` (see :mod:`probeless.bench.pbgi`)."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

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
