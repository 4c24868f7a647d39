"""Pictures of the textured coarse model (paper Figures 4 and 8): the prism from a viewpoint, with frusta.

:func:`overview_camera` looks into the room from above a corner with the ceiling left out (a
"dollhouse" view); :func:`inside_camera` looks across the room from inside. Frusta and
trajectories are drawn as coloured lines (RGB-D camera green, fisheye orange).
"""

from __future__ import annotations

from pathlib import Path

import moderngl
import numpy as np

from probeless.coarse.atlas import AtlasLayout
from probeless.coarse.texels import coarse_mesh
from probeless.geom.projection import clip_from_camera
from probeless.gl.context import create_context, current_context
from probeless.gl.programs import load_program, mat_bytes
from probeless.gl.textures import upload_texture

SHADERS = Path(__file__).with_name("shaders")
GREEN, ORANGE, WHITE = (0.2, 0.9, 0.3), (1.0, 0.55, 0.1), (1.0, 1.0, 1.0)


def look_at(eye: np.ndarray, target: np.ndarray, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """world_from_camera (4, 4) of an OpenCV camera (z forward, y down) at ``eye`` looking at ``target``."""
    z = np.asarray(target, float) - np.asarray(eye, float)
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    x = x / np.linalg.norm(x) if np.linalg.norm(x) > 1e-9 else np.array([1.0, 0, 0])
    T = np.eye(4)
    T[:3, :3] = np.stack([x, np.cross(z, x), z], axis=1)
    T[:3, 3] = eye
    return T


def overview_camera(layout: AtlasLayout) -> np.ndarray:
    """A camera above and outside the room's south-west corner looking at its centre."""
    lo, hi = layout.floorplan.min(axis=0), layout.floorplan.max(axis=0)
    c, ext = (lo + hi) / 2, float(np.max(hi - lo))
    eye = np.array([lo[0] - 0.15 * ext, lo[1] - 0.35 * ext, layout.ceiling_height + 0.8 * ext])
    return look_at(eye, np.array([c[0], c[1], 0.3 * layout.ceiling_height]))


def inside_camera(layout: AtlasLayout, position: np.ndarray | None = None) -> np.ndarray:
    """A camera at ``position`` (default: near the room's centroid, 1.4 m up) looking across the room."""
    poly = layout.floorplan
    centre = poly.mean(axis=0) if position is None else np.asarray(position, float)[:2]
    far = poly[np.argmax(np.linalg.norm(poly - centre, axis=1))]
    z = 1.4 if position is None else float(position[2])
    return look_at(np.array([*centre, z]), np.array([far[0], far[1], 0.6 * layout.ceiling_height]))


def frustum_lines(world_from_camera: np.ndarray, K: np.ndarray, size: tuple[int, int], depth: float) -> np.ndarray:
    """(2L, 3) line-segment endpoints of a pinhole frustum ``depth`` metres deep."""
    w, h = size
    corners = np.array([[0, 0], [w, 0], [w, h], [0, h]], float)
    rays = np.c_[(corners - K[:2, 2]) / np.diag(K)[:2], np.ones(4)] * depth
    pts = rays @ world_from_camera[:3, :3].T + world_from_camera[:3, 3]
    o = world_from_camera[:3, 3]
    segs = [(o, p) for p in pts] + [(pts[i], pts[(i + 1) % 4]) for i in range(4)]
    return np.array(segs, float).reshape(-1, 3)


def fisheye_lines(world_from_fisheye: np.ndarray, fov_deg: float, length: float, n: int = 16) -> np.ndarray:
    """A cone of ``n`` rays at half the field of view, a ring joining them, and the optical axis."""
    half = np.radians(min(fov_deg, 179.0) / 2)
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    rays = np.stack([np.sin(half) * np.cos(a), np.sin(half) * np.sin(a), np.full(n, np.cos(half))], axis=1) * length
    pts = rays @ world_from_fisheye[:3, :3].T + world_from_fisheye[:3, 3]
    o = world_from_fisheye[:3, 3]
    axis = o + world_from_fisheye[:3, 2] * length
    segs = [(o, p) for p in pts] + [(pts[i], pts[(i + 1) % n]) for i in range(n)] + [(o, axis)]
    return np.array(segs, float).reshape(-1, 3)


def polyline(points: np.ndarray) -> np.ndarray:
    """Segment endpoints joining consecutive ``points`` (N, 3)."""
    p = np.asarray(points, float)
    return np.repeat(p, 2, axis=0)[1:-1] if len(p) > 1 else np.zeros((0, 3))


class ModelView:
    """Renders the prism textured with an atlas image, plus coloured line sets."""

    def __init__(self, layout: AtlasLayout, *, ctx: moderngl.Context | None = None):
        self.ctx = ctx or create_context()
        v, t, uv, surface = coarse_mesh(layout)
        self.ceiling = np.flatnonzero([s.kind == "ceiling" for s in layout.surfaces])[0]
        order = np.argsort(surface == self.ceiling, kind="stable")  # ceiling triangles last
        tris = t[order]
        self.n_no_ceiling = int(np.sum(surface != self.ceiling))
        self.n_all = len(tris)
        data = np.hstack([v, uv]).astype("f4")
        self.mesh_prog = load_program(self.ctx, "meshview", shader_dir=SHADERS, vertex="textured_mesh")
        self.line_prog = load_program(self.ctx, "lines", shader_dir=SHADERS)
        self.vbo = self.ctx.buffer(data.tobytes())
        self.ibo = self.ctx.buffer(tris.astype("i4").tobytes())
        self.vao = self.ctx.vertex_array(self.mesh_prog, [(self.vbo, "3f 2f", "in_position", "in_uv")],
                                         index_buffer=self.ibo)
        self.layout = layout

    @current_context
    def render(self, atlas_rgb: np.ndarray, world_from_camera: np.ndarray, K: np.ndarray, size: tuple[int, int],
               lines: list[tuple[np.ndarray, tuple]] = (), ceiling: bool = True) -> np.ndarray:
        """(H, W, 3) uint8 view; ``atlas_rgb`` (H, W, 3) uint8 or float 0..1, row 0 = atlas top."""
        w, h = size
        img = np.asarray(atlas_rgb)
        img = (np.clip(img, 0, 1) * 255).astype(np.uint8) if img.dtype != np.uint8 else img
        tex = upload_texture(self.ctx, img[::-1, :, :3], filter="trilinear", repeat=True)
        fbo = self.ctx.simple_framebuffer((w, h))
        fbo.use()
        fbo.clear(0.08, 0.08, 0.1, 1.0)
        self.ctx.enable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        self.ctx.front_face = "cw"  # the OpenCV projection (y down) mirrors the winding
        clip = mat_bytes(clip_from_camera(K, w, h, 0.05, 100.0) @ np.linalg.inv(world_from_camera))
        self.mesh_prog["clip_from_world"].write(clip)
        tex.use(0)
        self.mesh_prog["atlas"] = 0
        count = 3 * (self.n_all if ceiling else self.n_no_ceiling)
        self.vao.render(moderngl.TRIANGLES, vertices=count)
        self.ctx.disable(moderngl.CULL_FACE)
        self.line_prog["clip_from_world"].write(clip)
        for segs, color in lines:
            if len(segs):
                vbo = self.ctx.buffer(np.asarray(segs, "f4").tobytes())
                vao = self.ctx.vertex_array(self.line_prog, [(vbo, "3f", "in_position")])
                self.line_prog["color"] = tuple(color)
                vao.render(moderngl.LINES)
                vao.release()
                vbo.release()
        out = np.frombuffer(fbo.read(components=3), np.uint8).reshape(h, w, 3).copy()
        tex.release()
        fbo.release()
        return out
