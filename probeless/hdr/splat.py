"""Unlighted renderings of a coloured point cloud by point splatting, with a per-pixel point id (paper 001, §4.1).

The paper renders the LDR cloud with "a simple point splatting algorithm" at 1024 x 1024 from a few
positions and keeps each rendering's intrinsics and extrinsics to project the image data back onto
the points. Here every pixel also carries the id (row in ``points``) of the point drawn there, so the
back-projection is exact rather than a nearest-point search.

Splats: each point is a round splat of world radius ``radius_scale * spacing`` (``spacing`` from
:func:`point_spacing`), shaped as the front half of a sphere for the depth test (splats of one
surface meet along the Voronoi edges of their centres; surfaces further apart than a radius occlude
properly). Screen size falls with distance as in :mod:`probeless.envmap.cubemap`; a point sprite is at
most ``max_px`` wide (and at most the GL limit, 255 px on llvmpipe), so a nearer splat is cut to that
square. Splats are never smaller than the pixel their centre falls in, so far points still show.

Camera convention: OpenCV (x right, y down, z forward), ``world_from_camera`` a 4 x 4 rigid map of
camera coordinates to world; image row 0 is the top row (:func:`probeless.geom.projection.clip_from_camera`).
Cube faces follow :mod:`probeless.geom.cube` (their camera frames are mirrored: det R = -1).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import moderngl
import numpy as np
from scipy.spatial import cKDTree

from probeless.envmap.cubemap import face_buckets
from probeless.errors import HdrError
from probeless.geom.cube import CUBE_FACE_FRAMES
from probeless.geom.projection import clip_from_camera
from probeless.gl.context import create_context, current_context
from probeless.gl.programs import load_program, mat_bytes

SHADERS = Path(__file__).with_name("shaders")
DEFAULT_NEAR_M = 0.02


@dataclasses.dataclass(frozen=True, eq=False)
class View:
    """One rendering: ``color`` (H, W, 3) float32 (the points' colours, 0 = background), ``point_id``
    (H, W) int32 (row in the rendered ``points``, -1 = background), ``depth`` (H, W) float32 [m] (the
    drawn point's depth along the optical axis, 0 = background), ``K`` (3, 3), ``world_from_camera``
    (4, 4) float64 and ``size`` (width, height) [px]."""

    color: np.ndarray
    point_id: np.ndarray
    depth: np.ndarray
    K: np.ndarray
    world_from_camera: np.ndarray
    size: tuple[int, int]

    @property
    def mask(self) -> np.ndarray:
        """(H, W) bool: pixels with a point."""
        return self.point_id >= 0


def check_cloud(points, colors=None, spacing=None, what: str = "cloud") -> tuple[np.ndarray, ...]:
    """Validated (points (N, 3) float32, colours (N, 3) float32 or None, spacing (N,) float32 or None).

    Raises :class:`HdrError` naming the argument at fault: empty or non-(N, 3) ``points``, non-finite
    values, ``colors``/``spacing`` of another shape or length, non-positive spacing.
    """
    p = np.asarray(points)
    if p.ndim != 2 or p.shape[1] != 3:
        raise HdrError(f"{what}: points must be (N, 3), got shape {p.shape}")
    if len(p) == 0:
        raise HdrError(f"{what}: points is empty")
    if not np.issubdtype(p.dtype, np.number) or not np.isfinite(p).all():
        raise HdrError(f"{what}: points has non-finite values (NaN or inf)")
    out = [np.ascontiguousarray(p, np.float32)]
    if colors is not None:
        c = np.asarray(colors)
        if c.shape != p.shape:
            raise HdrError(f"{what}: colors must be (N, 3) like points {p.shape}, got shape {c.shape}")
        if not np.issubdtype(c.dtype, np.number) or not np.isfinite(c).all():
            raise HdrError(f"{what}: colors has non-finite values (NaN or inf)")
        out.append(np.ascontiguousarray(c, np.float32))
    else:
        out.append(None)
    if spacing is not None:
        s = np.asarray(spacing)
        if s.shape != (len(p),):
            raise HdrError(f"{what}: spacing must be (N,) = ({len(p)},), got shape {s.shape}")
        if not np.issubdtype(s.dtype, np.number) or not (np.isfinite(s).all() and (s > 0).all()):
            raise HdrError(f"{what}: spacing must be finite and > 0")
        out.append(np.ascontiguousarray(s, np.float32))
    else:
        out.append(None)
    return tuple(out)


def point_spacing(points: np.ndarray, k: int = 8) -> np.ndarray:
    """(N,) float32 local point spacing [m]: the mean distance of each point to its ``k`` nearest neighbours.

    Duplicate points count as neighbours at distance 0; a point whose neighbours all coincide with it
    gets the median spacing of the cloud (or 1 mm when every spacing is 0). A cloud of fewer than
    ``k + 1`` points uses the neighbours it has; a single point gets 1 mm.
    """
    p = check_cloud(points, what="point_spacing")[0].astype(np.float64)
    if not isinstance(k, (int, np.integer)) or k < 1:
        raise HdrError(f"point_spacing: k must be an integer >= 1, got {k!r}")
    kk = min(int(k), len(p) - 1)
    if kk < 1:
        return np.full(len(p), 1e-3, np.float32)
    d, _ = cKDTree(p).query(p, k=kk + 1, workers=-1)
    s = d[:, 1:].mean(axis=1)
    bad = s <= 0
    if bad.any():
        good = s[~bad]
        s[bad] = np.median(good) if len(good) else 1e-3
    return s.astype(np.float32)


def pinhole_size(size) -> tuple[int, int]:
    try:
        w, h = (int(x) for x in size)
    except (TypeError, ValueError) as exc:
        raise HdrError(f"size must be (width, height), got {size!r}") from exc
    if w < 1 or h < 1 or w > 16384 or h > 16384:
        raise HdrError(f"size must be (width, height) in 1..16384, got {size!r}")
    return w, h


class SplatRenderer:
    """Renders :class:`View`\\ s of a point cloud (colour, point id, depth) with round splats on the GPU.

    The last cloud drawn stays on the GPU: a call with equal ``(points, colors, spacing)`` values (compared
    on the CPU, a few ms per million points) draws it without uploading it again.
    """

    def __init__(self, ctx: moderngl.Context | None = None, *, radius_scale: float = 1.0, max_px: float = 128.0):
        self.ctx = ctx or create_context()
        self.radius_scale, self.max_px = float(radius_scale), float(max_px)
        self.prog = load_program(self.ctx, "splat_ids", shader_dir=SHADERS)
        lo, hi = self.ctx.info.get("GL_POINT_SIZE_RANGE", (1.0, 255.0))
        self.max_px = min(self.max_px, float(hi))
        self._cloud = None  # (key, arrays, vbo, vao)
        self._fbos: dict[tuple[int, int], moderngl.Framebuffer] = {}

    # -- GL objects ---------------------------------------------------------------------------------

    def _upload(self, points, colors, spacing, what: str):
        if self._cloud is not None and self._same_cloud(points, colors, spacing):
            return self._cloud
        p, c, s = check_cloud(points, colors, spacing, what)
        self._release_cloud()
        vbo = self.ctx.buffer(np.hstack([p, c, s[:, None]]).astype("f4").tobytes())
        vao = self.ctx.vertex_array(self.prog, [(vbo, "3f 3f 1f", "in_position", "in_color", "in_spacing")])
        self._cloud = (None, (p.copy(), c.copy(), s.copy(), p), vbo, vao)
        return self._cloud

    def _same_cloud(self, points, colors, spacing) -> bool:
        """Whether the arrays hold the uploaded cloud (compared by value: a few ms for a million points)."""
        for new, old in zip((points, colors, spacing), self._cloud[1][:3]):
            a = np.asarray(new)
            if a.shape != old.shape or not np.issubdtype(a.dtype, np.number) or not np.array_equal(a, old):
                return False
        return True

    def _release_cloud(self) -> None:
        if self._cloud is not None:
            self._cloud[3].release()
            self._cloud[2].release()
            self._cloud = None

    def _fbo(self, w: int, h: int) -> moderngl.Framebuffer:
        if (w, h) not in self._fbos:
            color = self.ctx.texture((w, h), 4, dtype="f4")
            ids = self.ctx.texture((w, h), 1, dtype="i4")
            depth = self.ctx.texture((w, h), 1, dtype="f4")
            for t in (color, ids, depth):
                t.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self._fbos[(w, h)] = self.ctx.framebuffer([color, ids, depth], self.ctx.depth_renderbuffer((w, h)))
        return self._fbos[(w, h)]

    def _draw(self, vao, p, K, world_from_camera, w, h, near, far, index=None) -> View:
        K = np.asarray(K, np.float64)
        pose = np.asarray(world_from_camera, np.float64)
        view = np.linalg.inv(pose)
        if far is None:
            # the farthest point plus a margin: depth is linear in [near, far]
            far = float(np.max(np.linalg.norm(p - pose[:3, 3].astype(np.float32), axis=1))) * 1.05 + 1.0
        if not (0 < near < far):
            raise HdrError(f"SplatRenderer.render: need 0 < near < far, got near={near}, far={far}")
        fbo = self._fbo(w, h)
        fbo.use()
        # integer and float attachments are cleared with the same bit pattern: 0 (id 0 = background)
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        ctx = self.ctx
        ctx.enable(moderngl.PROGRAM_POINT_SIZE | moderngl.DEPTH_TEST)
        ctx.disable(moderngl.BLEND | moderngl.CULL_FACE)
        ctx.depth_func = "<"
        prog = self.prog
        prog["clip_from_world"].write(mat_bytes(clip_from_camera(K, w, h, near, far) @ view))
        prog["camera_from_world"].write(mat_bytes(view))
        prog["focal_px"] = float(np.sqrt(abs(K[0, 0] * K[1, 1])))
        prog["radius_scale"] = self.radius_scale
        prog["max_px"] = self.max_px
        prog["viewport"] = (float(w), float(h))
        prog["near"], prog["far"] = float(near), float(far)
        if index is None:
            vao.render(moderngl.POINTS)
        elif index[2]:
            index[0].render(moderngl.POINTS, vertices=index[2], first=index[1])
        color = np.frombuffer(fbo.read(components=4, dtype="f4", attachment=0), np.float32).reshape(h, w, 4)
        ids = np.frombuffer(fbo.read(components=1, dtype="i4", attachment=1), np.int32).reshape(h, w) - 1
        depth = np.frombuffer(fbo.read(components=1, dtype="f4", attachment=2), np.float32).reshape(h, w)
        return View(np.ascontiguousarray(color[..., :3]), ids, depth.copy(), K.copy(), pose.copy(), (w, h))

    # -- public -------------------------------------------------------------------------------------

    @current_context
    def render(self, points: np.ndarray, colors: np.ndarray, spacing: np.ndarray, K: np.ndarray,
               world_from_camera: np.ndarray, size=(1024, 1024), near: float = DEFAULT_NEAR_M,
               far: float | None = None) -> View:
        """One pinhole :class:`View` of the cloud.

        ``points`` (N, 3) world [m], ``colors`` (N, 3) (any float units, written unchanged; linear in
        the paper), ``spacing`` (N,) [m] (:func:`point_spacing`), ``K`` (3, 3) OpenCV intrinsics,
        ``world_from_camera`` (4, 4), ``size`` (width, height) [px], ``near``/``far`` clip distances
        [m] (``far`` None: just past the farthest point).
        """
        w, h = pinhole_size(size)
        K = np.asarray(K, np.float64)
        pose = np.asarray(world_from_camera, np.float64)
        if K.shape != (3, 3) or not np.isfinite(K).all() or K[0, 0] <= 0 or K[1, 1] <= 0:
            raise HdrError(f"SplatRenderer.render: K must be finite (3, 3) with fx, fy > 0, got {K.tolist()}")
        if pose.shape != (4, 4) or not np.isfinite(pose).all() or abs(abs(np.linalg.det(pose[:3, :3])) - 1) > 1e-3:
            raise HdrError("SplatRenderer.render: world_from_camera must be a finite rigid (4, 4) matrix")
        _, arrays, _, vao = self._upload(points, colors, spacing, "SplatRenderer.render")
        return self._draw(vao, arrays[3], K, pose, w, h, float(near), far)

    @current_context
    def render_cubemap(self, points: np.ndarray, colors: np.ndarray, spacing: np.ndarray, position,
                       face_size: int = 512, near: float = DEFAULT_NEAR_M, far: float | None = None) -> list[View]:
        """Six 90-degree :class:`View`\\ s at ``position`` (3,) [m], faces and texel layout of
        :mod:`probeless.geom.cube` (view ``f``'s pixel (row, col) is cube texel [f, row, col]).

        Each face draws only the points in its frustum (:func:`probeless.envmap.cubemap.face_buckets`).
        The faces' ``world_from_camera`` rotations are the cube frames, mirrored (det -1): project with
        matrices (``K @ inv(world_from_camera)``), not with Rodrigues vectors.
        """
        pos = np.asarray(position, np.float64)
        if pos.shape != (3,) or not np.isfinite(pos).all():
            raise HdrError(f"render_cubemap: position must be 3 finite numbers, got {position!r}")
        if not isinstance(face_size, (int, np.integer)) or not 1 <= face_size <= 16384:
            raise HdrError(f"render_cubemap: face_size must be an integer in 1..16384, got {face_size!r}")
        _, arrays, vbo, _ = self._upload(points, colors, spacing, "render_cubemap")
        p = arrays[3]
        buckets = face_buckets(p, pos, margin=0.1)
        ibo = self.ctx.buffer(np.concatenate(buckets).astype("i4").tobytes())
        vao = self.ctx.vertex_array(self.prog, [(vbo, "3f 3f 1f", "in_position", "in_color", "in_spacing")],
                                    index_buffer=ibo)
        starts = np.cumsum([0] + [len(b) for b in buckets])
        if far is None:
            far = float(np.max(np.linalg.norm(p - pos.astype(np.float32), axis=1))) * 1.05 + 1.0
        try:
            half = face_size / 2.0
            K = np.array([[half, 0, half - 0.5], [0, half, half - 0.5], [0, 0, 1]])
            views = []
            for f in range(6):
                pose = np.eye(4)
                pose[:3, :3] = CUBE_FACE_FRAMES[f].T
                pose[:3, 3] = pos
                views.append(self._draw(None, p, K, pose, face_size, face_size, float(near), far,
                                        index=(vao, int(starts[f]), len(buckets[f]))))
            return views
        finally:
            vao.release()
            ibo.release()

    @current_context
    def release(self) -> None:
        """Free the GL objects (not the context)."""
        self._release_cloud()
        for fbo in self._fbos.values():
            for a in fbo.color_attachments:
                a.release()
            fbo.depth_attachment.release()
            fbo.release()
        self._fbos.clear()


def cloud_cubemap(renderer, points, colors, spacing, position, face: int) -> tuple[np.ndarray, np.ndarray]:
    """((6, face, face, 3) float32 cubemap of the cloud's colours at ``position``, 0 where no point;
    (6, face, face) bool: a point covers the texel)."""
    views = renderer.render_cubemap(points, colors.astype(np.float32), spacing, np.asarray(position, np.float64),
                                    face)
    return np.stack([v.color for v in views]).astype(np.float32), np.stack([v.mask for v in views])
