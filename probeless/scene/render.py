"""OpenGL renderer of a SceneGeometry: pinhole RGB-D, cubemaps and per-pixel ray images (e.g. fisheye).

Implements the shading model documented in :mod:`probeless.scene.geometry` with float32 render
targets on a headless context. Nothing is culled; lighting is two-sided (the normal is flipped
towards the viewer, so single-sided geometry seen from behind shades like its front). Shadow maps
(one distance cube per light, from the light's centre 5 mm along its normal) are rendered once at
construction: the scene is static. The GL context is current on the thread that created it.
"""

from __future__ import annotations

from pathlib import Path

import moderngl
import numpy as np

from probeless.errors import SceneError
from probeless.geom.cube import cube_face_clip_from_world
from probeless.geom.projection import clip_from_camera
from probeless.gl.context import GL_TEXTURE_CUBE_MAP_SEAMLESS, create_context, current_context
from probeless.gl.programs import load_program, mat_bytes, set_uniforms
from probeless.gl.textures import copy_to_cube_face, float_target, upload_texture
from probeless.scene.geometry import AreaLight, SceneGeometry

SHADERS = Path(__file__).with_name("shaders")

SHADOW_OFFSET_M = 0.005  # shadow-map origin in front of the light panel [m]
SHADOW_NEAR_M = 0.001
CUBE_NEAR_M = 0.01


def check_geometry(geometry: SceneGeometry) -> None:
    """Raise SceneError naming the first surface whose arrays cannot be drawn."""
    if not geometry.surfaces:
        raise SceneError("SceneGeometry.surfaces: empty, nothing to render")
    for s in geometry.surfaces:
        n = len(s.positions)
        if n == 0 or n % 3 or s.positions.shape != (n, 3) or s.normals.shape != (n, 3) or s.uvs.shape != (n, 2):
            raise SceneError(f"surface '{s.name}': positions {s.positions.shape}, normals {s.normals.shape}, "
                             f"uvs {s.uvs.shape}; expected (3T, 3), (3T, 3), (3T, 2) with T >= 1")
        if not -1 <= s.light_index < len(geometry.lights):
            raise SceneError(f"surface '{s.name}': light_index {s.light_index} but {len(geometry.lights)} lights")
        if s.texture is not None and (s.texture.ndim != 3 or s.texture.shape[2] != 3):
            raise SceneError(f"surface '{s.name}': texture shape {s.texture.shape}, expected (H, W, 3)")


def shadow_origin(light: AreaLight) -> np.ndarray:
    """Where a light's shadow cube is rendered from [m, world]."""
    return np.asarray(light.center, np.float64) + SHADOW_OFFSET_M * np.asarray(light.normal, np.float64)


def light_uniforms(lights: tuple[AreaLight, ...], scale: np.ndarray, samples: int) -> dict[str, np.ndarray]:
    """The shade program's per-light arrays (float32 rows), radiance pre-multiplied by s_i * area / n^2."""
    power = [s * np.asarray(x.radiance, np.float64) * x.area / samples ** 2 for s, x in zip(scale, lights)]
    rows = {"light_center": [x.center for x in lights], "light_u": [x.half_u for x in lights],
            "light_v": [x.half_v for x in lights], "light_normal": [x.normal for x in lights],
            "light_power": power, "shadow_origin": [shadow_origin(x) for x in lights]}
    return {k: np.asarray(v, np.float32).reshape(len(lights), 3) for k, v in rows.items()}


class SceneRenderer:
    """Draws one static SceneGeometry; every render call takes the lights' on/off scales."""

    def __init__(self, geometry: SceneGeometry, *, ctx: moderngl.Context | None = None,
                 shadow_size: int = 512, light_samples: int = 4):
        check_geometry(geometry)
        if shadow_size < 1 or light_samples < 1:
            raise SceneError(f"SceneRenderer: shadow_size {shadow_size} and light_samples {light_samples} must be >= 1")
        self.geometry, self._own_ctx = geometry, ctx is None
        self.ctx = create_context() if ctx is None else ctx
        self.ctx.__enter__()
        ctx, n_lights = self.ctx, len(geometry.lights)
        if n_lights >= ctx.max_texture_units:
            raise SceneError(f"SceneGeometry.lights: {n_lights} lights, this GL allows {ctx.max_texture_units - 1}")
        ctx.enable_direct(GL_TEXTURE_CUBE_MAP_SEAMLESS)
        self._shadow_size, self._samples = shadow_size, light_samples
        self._shade = load_program(ctx, "shade", {"NUM_LIGHTS": n_lights, "LIGHT_SAMPLES": light_samples}, SHADERS)
        self._shadow = load_program(ctx, "shadow", shader_dir=SHADERS)
        self._rays = load_program(ctx, "rays", shader_dir=SHADERS)
        self._copy = {c: load_program(ctx, "cubecopy", {"FORMAT": f}) for c, f in ((4, "rgba32f"), (1, "r32f"))}
        self._surfaces = sorted(geometry.surfaces, key=lambda s: s.emissive)  # shadow casters first
        data = np.concatenate([np.hstack([s.positions, s.normals, s.uvs]) for s in self._surfaces])
        self._vbo = ctx.buffer(data.astype("f4").tobytes())
        self._shade_vao = ctx.vertex_array(
            self._shade, [(self._vbo, "3f 3f 2f", "in_position", "in_normal", "in_uv")], skip_errors=True)
        self._shadow_vao = ctx.vertex_array(self._shadow, [(self._vbo, "3f 20x", "in_position")])
        self._ray_vao = ctx.vertex_array(self._rays, [])
        starts = np.cumsum([0] + [len(s.positions) for s in self._surfaces]).tolist()
        self._ranges = list(zip(starts[:-1], np.diff(starts).tolist()))
        self._casters = sum(len(s.positions) for s in self._surfaces if not s.emissive)
        self._white = ctx.texture((1, 1), 3, np.ones(3, "f4").tobytes(), dtype="f4")
        self._textures = [self._white if s.texture is None else
                          upload_texture(ctx, s.texture, filter="trilinear", repeat=True)  # tiled albedo
                          for s in self._surfaces]
        lo, hi = geometry.bounds()
        self._far = 2.0 * float(np.linalg.norm(hi - lo)) + 1.0
        self._targets: dict[tuple[int, int, int], moderngl.Framebuffer] = {}
        self._env: moderngl.TextureCube | None = None
        self._ray_tex: tuple[np.ndarray, moderngl.Texture] | None = None
        self._shadow_maps = [self._render_shadow_map(light) for light in geometry.lights]

    def _target(self, width: int, height: int, components: int = 4) -> moderngl.Framebuffer:
        if (width, height, components) not in self._targets:
            self._targets[width, height, components] = float_target(self.ctx, width, height, components)
        return self._targets[width, height, components]

    def _render_shadow_map(self, light: AreaLight) -> moderngl.TextureCube:
        size, origin = self._shadow_size, shadow_origin(light)
        fbo = self._target(size, size, 1)
        cube = self.ctx.texture_cube((size, size), 1, dtype="f4")
        cube.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self._shadow["origin"] = tuple(origin)
        for face, clip in enumerate(cube_face_clip_from_world(origin, size, SHADOW_NEAR_M, self._far)):
            fbo.use()
            self.ctx.enable_only(moderngl.DEPTH_TEST)
            self.ctx.depth_func = "<"
            fbo.clear(1e30, 1e30, 1e30, 1e30, depth=1.0)  # nothing there: lit
            self._shadow["clip_from_world"].write(mat_bytes(clip))
            self._shadow_vao.render(moderngl.TRIANGLES, vertices=self._casters, first=0)
            copy_to_cube_face(self.ctx, self._copy[1], fbo.color_attachments[0], cube, face)
        return cube

    def _set_lights(self, light_scale: np.ndarray) -> np.ndarray:
        lights = self.geometry.lights
        scale = np.asarray(light_scale, dtype=np.float64).reshape(-1)
        if scale.shape != (len(lights),) or not np.all(np.isfinite(scale)):
            raise SceneError(f"light_scale: expected {len(lights)} finite values, one per geometry.lights "
                             f"{[x.name for x in lights]}; got shape {np.shape(light_scale)}")
        ambient = sum((s * np.asarray(x.ambient, np.float64) for s, x in zip(scale, lights)), np.zeros(3))
        set_uniforms(self._shade, ambient=tuple(ambient), shadow_texel=2.0 / self._shadow_size)
        for name, rows in (light_uniforms(lights, scale, self._samples) if lights else {}).items():
            self._shade[name].write(rows.tobytes())
        if lights and "shadow_maps" in self._shade:
            self._shade["shadow_maps"].write(np.arange(1, len(lights) + 1, dtype="i4").tobytes())
        for unit, cube in enumerate(self._shadow_maps, start=1):
            cube.use(unit)
        return scale

    def _draw(self, fbo: moderngl.Framebuffer, clip_from_world: np.ndarray, eye: np.ndarray, depth_row: np.ndarray,
              scale: np.ndarray) -> None:
        prog = self._shade
        fbo.use()
        self.ctx.enable_only(moderngl.DEPTH_TEST)
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        # Depth pre-pass (position-only program): each pixel is then shaded once, not once per layer.
        self._shadow["clip_from_world"].write(mat_bytes(clip_from_world))
        fbo.color_mask = (False, False, False, False)
        self._shadow_vao.render(moderngl.TRIANGLES)
        fbo.color_mask = (True, True, True, True)
        self.ctx.depth_func = "<="
        prog["clip_from_world"].write(mat_bytes(clip_from_world))
        set_uniforms(prog, depth_row=tuple(depth_row), eye=tuple(eye), albedo_tex=0)
        for s, tex, (first, count) in zip(self._surfaces, self._textures, self._ranges):
            on = 1.0 if s.light_index < 0 else float(scale[s.light_index])
            set_uniforms(prog, emissive=int(s.emissive), color=tuple(np.asarray(s.color, np.float64)),
                         emission=tuple(np.asarray(s.emission, np.float64) * on))
            tex.use(0)
            self._shade_vao.render(moderngl.TRIANGLES, vertices=count, first=first)

    @current_context
    def render_pinhole(self, world_from_camera: np.ndarray, K: np.ndarray, width: int, height: int,
                       light_scale: np.ndarray, near: float = 0.05,
                       far: float = 100.0) -> tuple[np.ndarray, np.ndarray]:
        """Radiance (H, W, 3) and depth (H, W) [m along the optical axis, 0 = nothing] of an OpenCV pinhole."""
        scale = self._set_lights(light_scale)
        pose = np.asarray(world_from_camera, np.float64)
        view = np.linalg.inv(pose)
        fbo = self._target(width, height)
        clip = clip_from_camera(np.asarray(K, np.float64), width, height, near, far) @ view
        self._draw(fbo, clip, pose[:3, 3], view[2], scale)
        out = np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32).reshape(height, width, 4)
        return np.ascontiguousarray(out[..., :3]), np.ascontiguousarray(out[..., 3])

    @current_context
    def render_clip(self, clip_from_world: np.ndarray, eye: np.ndarray, width: int, height: int,
                    light_scale: np.ndarray) -> np.ndarray:
        """Radiance (H, W, 3) through any projection ``clip_from_world`` (e.g. orthographic); row 0 = clip y -1."""
        scale = self._set_lights(light_scale)
        fbo = self._target(width, height)
        self._draw(fbo, np.asarray(clip_from_world, np.float64), np.asarray(eye, np.float64), np.zeros(4), scale)
        out = np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32).reshape(height, width, 4)
        return np.ascontiguousarray(out[..., :3])

    def _faces(self, position: np.ndarray, size: int, scale: np.ndarray):
        """Yield (face, framebuffer) once face ``face`` of the cube seen from ``position`` is drawn in it."""
        position = np.asarray(position, np.float64).reshape(3)
        fbo = self._target(size, size)
        for face, clip in enumerate(cube_face_clip_from_world(position, size, CUBE_NEAR_M, self._far)):
            self._draw(fbo, clip, position, np.zeros(4), scale)
            yield face, fbo

    @current_context
    def render_cubemap(self, position: np.ndarray, size: int, light_scale: np.ndarray) -> np.ndarray:
        """(6, size, size, 3) radiance seen from ``position`` in the probeless.messages.lighting convention."""
        faces = np.empty((6, size, size, 3), np.float32)
        for face, fbo in self._faces(position, size, self._set_lights(light_scale)):
            faces[face] = np.frombuffer(fbo.read(components=3, dtype="f4"), np.float32).reshape(size, size, 3)
        return faces

    def _ray_texture(self, rays: np.ndarray) -> moderngl.Texture:
        if self._ray_tex is None or self._ray_tex[0] is not rays:
            if rays.ndim != 3 or rays.shape[2] != 3:
                raise SceneError(f"render_rays: rays shape {rays.shape}, expected (H, W, 3)")
            clean = np.where(np.all(np.isfinite(rays), axis=2, keepdims=True), rays, 0.0).astype("f4")
            tex = upload_texture(self.ctx, clean, self._ray_tex[1] if self._ray_tex else None, repeat=True)
            self._ray_tex = (rays, tex)  # holding the array keeps its id from being reused
        return self._ray_tex[1]

    @current_context
    def render_rays(self, world_from_camera: np.ndarray, rays: np.ndarray, light_scale: np.ndarray,
                    cube_size: int = 512) -> np.ndarray:
        """(H, W, 3) radiance along camera-frame unit ``rays`` (H, W, 3) from the camera centre; 0 where invalid.

        Renders a cube at the camera centre, then samples it per pixel on the GPU (bilinear,
        seamless). Zero or non-finite rays are invalid. The ray texture is cached by array
        identity: pass a new array (not an in-place edit) when the rays change.
        """
        scale = self._set_lights(light_scale)
        pose = np.asarray(world_from_camera, np.float64)
        if self._env is None or self._env.size != (cube_size, cube_size):
            if self._env is not None:
                self._env.release()
            self._env = self.ctx.texture_cube((cube_size, cube_size), 4, dtype="f4")
        for face, fbo in self._faces(pose[:3, 3], cube_size, scale):
            copy_to_cube_face(self.ctx, self._copy[4], fbo.color_attachments[0], self._env, face)
        height, width = rays.shape[:2]
        fbo = self._target(width, height)
        fbo.use()
        self.ctx.enable_only(moderngl.NOTHING)
        self._ray_texture(rays).use(0)
        self._env.use(1)
        self._rays["rays"], self._rays["environment"] = 0, 1
        self._rays["world_from_camera"].write(mat_bytes(pose[:3, :3]))
        self._ray_vao.render(moderngl.TRIANGLES, vertices=3)
        return np.frombuffer(fbo.read(components=3, dtype="f4"), np.float32).reshape(height, width, 3).copy()

    @current_context
    def release(self) -> None:
        """Free every GL object (and the context when this renderer created it)."""
        owned = [self._vbo, self._shade_vao, self._shadow_vao, self._ray_vao, self._white, self._shade,
                 self._shadow, self._rays, *self._copy.values(), *self._textures, *self._shadow_maps]
        owned += [self._env] if self._env else []
        owned += [self._ray_tex[1]] if self._ray_tex else []
        for fbo in self._targets.values():
            owned += [*fbo.color_attachments, fbo.depth_attachment, fbo]
        for obj in owned:
            obj.release()  # releasing twice (the shared white texture) is a no-op in moderngl
        self._targets.clear()
        if self._own_ctx:
            self.ctx.release()
