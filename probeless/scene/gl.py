"""OpenGL plumbing for the scene renderer: headless context, shader files, camera and cube-face matrices.

Shaders live in ``shaders/`` next to this module, one program per name: ``NAME.vert.glsl`` +
``NAME.frag.glsl`` (optionally ``NAME.geom.glsl``), or ``NAME.comp.glsl`` for a compute shader.
A line ``#include "FILE.glsl"`` is replaced by that file, from the shader's folder or else from
``probeless/glsl/`` (functions several programs share, e.g. ``fresnel.glsl``).

Matrices are float64 numpy, row-major (``clip = M @ [x, y, z, 1]``); :func:`mat_bytes` packs
them the way GLSL ``mat3``/``mat4`` uniforms expect (column-major float32).
"""

from __future__ import annotations

import functools
import re
from pathlib import Path

import moderngl
import numpy as np

from probeless.errors import DeviceError

SHADER_DIR = Path(__file__).with_name("shaders")
INCLUDE_DIR = Path(__file__).parents[1] / "glsl"
_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$')
GL_TEXTURE_CUBE_MAP_SEAMLESS = 0x884F
GL_RGBA32F, GL_R32F = 0x8814, 0x822E

# Rows (U, V, F) of each cube face frame, face order +X, -X, +Y, -Y, +Z, -Z: texel (a, b) of a
# face looks along F + a U + b V (the OpenGL table in probeless.messages.lighting).
CUBE_FACE_FRAMES = np.array([
    [(0, 0, -1), (0, -1, 0), (1, 0, 0)],
    [(0, 0, 1), (0, -1, 0), (-1, 0, 0)],
    [(1, 0, 0), (0, 0, 1), (0, 1, 0)],
    [(1, 0, 0), (0, 0, -1), (0, -1, 0)],
    [(1, 0, 0), (0, -1, 0), (0, 0, 1)],
    [(-1, 0, 0), (0, -1, 0), (0, 0, -1)],
], dtype=np.float64)


def create_context(require: int = 430) -> moderngl.Context:
    """A standalone headless (EGL) OpenGL context of at least version ``require`` (430: compute shaders)."""
    try:
        return moderngl.create_standalone_context(backend="egl", require=require)
    except Exception as exc:  # moderngl/glcontext raise plain Exception subclasses
        raise DeviceError(f"OpenGL: cannot create a headless EGL context with GL >= {require / 100:.2f}: "
                          f"{exc}") from exc


def load_program(ctx: moderngl.Context, name: str, defines: dict[str, object] | None = None,
                 shader_dir: Path = SHADER_DIR, vertex: str | None = None):
    """Compile ``shader_dir/NAME.*.glsl`` into a Program (or ComputeShader), ``#define``s inserted after ``#version``.

    ``shader_dir`` defaults to this module's ``shaders/``; other packages pass the folder next to their node.
    ``vertex`` names another program whose vertex shader this one shares (e.g. a full-screen pass).
    """
    def source(stage: str) -> str | None:
        path = shader_dir / f"{vertex if stage == 'vert' and vertex else name}.{stage}.glsl"
        if not path.exists():
            return None
        head, _, body = path.read_text().partition("\n")
        extra = "".join(f"#define {k} {v}\n" for k, v in (defines or {}).items())
        return f"{head}\n{extra}#line 2\n{expand_includes(body, path, shader_dir, first_line=2)}"

    stages = {stage: source(stage) for stage in ("vert", "frag", "geom", "comp")}
    try:
        if stages["comp"] is not None:
            return ctx.compute_shader(stages["comp"])
        if stages["vert"] is None or stages["frag"] is None:
            raise DeviceError(f"shader '{name}': need {name}.vert.glsl and {name}.frag.glsl (or {name}.comp.glsl) "
                              f"in {shader_dir}")
        return ctx.program(vertex_shader=stages["vert"], fragment_shader=stages["frag"],
                           geometry_shader=stages["geom"])
    except moderngl.Error as exc:
        raise DeviceError(f"shader '{name}' ({shader_dir}) failed to build on "
                          f"{ctx.info['GL_RENDERER']}: {exc}") from exc


def expand_includes(body: str, path: Path, shader_dir: Path, first_line: int = 1) -> str:
    """``body`` (the lines of ``path`` from ``first_line`` on) with each ``#include "FILE"`` line
    replaced by FILE from ``shader_dir`` or :data:`INCLUDE_DIR`, and a ``#line`` after it so
    compiler messages keep the including file's line numbers. Included files include nothing."""
    out = []
    for n, line in enumerate(body.splitlines(), start=first_line):
        m = _INCLUDE.match(line)
        if not m:
            out.append(line)
            continue
        found = next((d / m[1] for d in (shader_dir, INCLUDE_DIR) if (d / m[1]).is_file()), None)
        if found is None:
            raise DeviceError(f"{path}:{n}: #include \"{m[1]}\" is neither in {shader_dir} nor in {INCLUDE_DIR}")
        text = found.read_text()
        if any(_INCLUDE.match(x) for x in text.splitlines()):
            raise DeviceError(f"{found}: an included file cannot #include (included from {path}:{n})")
        out += [text.rstrip("\n"), f"#line {n + 1}"]
    return "\n".join(out) + "\n"


def current_context(method):
    """Decorator: make ``self.ctx`` current before the method runs. Several GL objects owning contexts
    may share a thread; the context stays current afterwards so the caller's GL calls keep working."""

    @functools.wraps(method)
    def wrapper(self, *args, **kwargs):
        self.ctx.__enter__()
        return method(self, *args, **kwargs)

    return wrapper


def set_uniforms(prog: moderngl.Program, **values) -> None:
    """Set uniforms by name, skipping those the GLSL compiler removed as unused (e.g. lighting with no lights)."""
    for name, value in values.items():
        if name in prog:
            prog[name] = value


def float_target(ctx: moderngl.Context, width: int, height: int, components: int = 4) -> moderngl.Framebuffer:
    """A framebuffer with one float32 colour texture (R32F / RGBA32F, nearest filtering) and a depth buffer."""
    color = ctx.texture((width, height), components, dtype="f4")
    color.filter = (moderngl.NEAREST, moderngl.NEAREST)
    return ctx.framebuffer([color], ctx.depth_renderbuffer((width, height)))


def albedo_texture(ctx: moderngl.Context, image: np.ndarray) -> moderngl.Texture:
    """An (H, W, 3) linear float image as a tiled (GL_REPEAT), trilinear mipmapped RGB32F texture."""
    h, w, _ = image.shape
    tex = ctx.texture((w, h), 3, np.ascontiguousarray(image, "f4").tobytes(), dtype="f4")
    tex.repeat_x = tex.repeat_y = True
    tex.build_mipmaps()
    tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
    return tex


def copy_to_cube_face(ctx: moderngl.Context, copy_prog, image: moderngl.Texture, cube: moderngl.TextureCube,
                      face: int) -> None:
    """GPU copy of a square float texture into ``face`` of ``cube`` (``copy_prog`` = cubecopy built for its format)."""
    size = cube.size[0]
    image.use(0)
    copy_prog["face_image"], copy_prog["face"], copy_prog["size"] = 0, face, size
    cube.bind_to_image(0, read=False, write=True, format=GL_RGBA32F if cube.components == 4 else GL_R32F)
    copy_prog.run((size + 7) // 8, (size + 7) // 8, 1)
    ctx.memory_barrier()


def mat_bytes(m: np.ndarray) -> bytes:
    """A row-major numpy matrix as the column-major float32 bytes of a GLSL matrix uniform."""
    return np.ascontiguousarray(np.asarray(m, dtype=np.float64).T, dtype=np.float32).tobytes()


def clip_from_camera(K: np.ndarray, width: int, height: int, near: float, far: float) -> np.ndarray:
    """4x4 projection of an OpenCV pinhole (x right, y down, z forward) into GL clip space.

    Pixel (u, v) centres sit at integer coordinates; image row v = 0 lands on framebuffer row 0
    (the first row ``glReadPixels`` returns), so read-back arrays need no flip.
    """
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    return np.array([
        [2 * fx / width, K[0, 1] * 2 / width, 2 * (cx + 0.5) / width - 1, 0],
        [0, 2 * fy / height, 2 * (cy + 0.5) / height - 1, 0],
        [0, 0, (far + near) / (far - near), -2 * far * near / (far - near)],
        [0, 0, 1, 0],
    ], dtype=np.float64)


def view_from_world(rotation_rows: np.ndarray, position: np.ndarray) -> np.ndarray:
    """4x4 rigid map x -> R (x - position), R = the camera axes as rows in world coordinates."""
    m = np.eye(4)
    m[:3, :3] = rotation_rows
    m[:3, 3] = -rotation_rows @ np.asarray(position, dtype=np.float64)
    return m


def cube_face_clip_from_world(position: np.ndarray, size: int, near: float, far: float) -> list[np.ndarray]:
    """Six 90-degree clip_from_world matrices whose framebuffer texel (row, col) is cube texel [face, row, col]."""
    half = size / 2.0
    K = np.array([[half, 0, half - 0.5], [0, half, half - 0.5], [0, 0, 1]])
    proj = clip_from_camera(K, size, size, near, far)
    return [proj @ view_from_world(CUBE_FACE_FRAMES[f], position) for f in range(6)]
