"""Shader programs: loading shader files, ``#include``, uniforms and matrix uniforms.

Shaders live in a package's ``shaders/`` folder, one program per name: ``NAME.vert.glsl`` +
``NAME.frag.glsl`` (optionally ``NAME.geom.glsl``), or ``NAME.comp.glsl`` for a compute shader.
:func:`load_program` looks in the folder it is given, then in :data:`SHADER_DIR` (programs several
packages share, e.g. ``fullscreen.vert.glsl`` and ``cubecopy.comp.glsl``). A line
``#include "FILE.glsl"`` is replaced by that file, from the shader's folder or else from
:data:`INCLUDE_DIR` (functions several programs share, e.g. ``fresnel.glsl``).

Matrices are float64 numpy, row-major (``clip = M @ [x, y, z, 1]``; :mod:`probeless.geom.projection`);
:func:`mat_bytes` packs them the way GLSL ``mat3``/``mat4`` uniforms expect (column-major float32).
"""

from __future__ import annotations

import re
from pathlib import Path

import moderngl
import numpy as np

from probeless.errors import DeviceError

SHADER_DIR = Path(__file__).with_name("shaders")
INCLUDE_DIR = Path(__file__).with_name("glsl")
_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$')


def load_program(ctx: moderngl.Context, name: str, defines: dict[str, object] | None = None,
                 shader_dir: Path = SHADER_DIR, vertex: str | None = None):
    """Compile ``shader_dir/NAME.*.glsl`` into a Program (or ComputeShader), ``#define``s inserted after ``#version``.

    Each stage file is taken from ``shader_dir`` (a package passes its own ``shaders/``) or else from
    :data:`SHADER_DIR`. ``vertex`` names another program whose vertex shader this one shares (e.g.
    ``"fullscreen"``, the shared one-triangle full-screen pass).
    """
    def source(stage: str) -> str | None:
        file = f"{vertex if stage == 'vert' and vertex else name}.{stage}.glsl"
        path = next((d / file for d in (shader_dir, SHADER_DIR) if (d / file).is_file()), None)
        if path is None:
            return None
        head, _, body = path.read_text().partition("\n")
        extra = "".join(f"#define {k} {v}\n" for k, v in (defines or {}).items())
        return f"{head}\n{extra}#line 2\n{expand_includes(body, path, path.parent, first_line=2)}"

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


def set_uniforms(prog: moderngl.Program, **values) -> None:
    """Set uniforms by name, skipping those the GLSL compiler removed as unused (e.g. lighting with no lights)."""
    for name, value in values.items():
        if name in prog:
            prog[name] = value


def mat_bytes(m: np.ndarray) -> bytes:
    """A row-major numpy matrix as the column-major float32 bytes of a GLSL matrix uniform."""
    return np.ascontiguousarray(np.asarray(m, dtype=np.float64).T, dtype=np.float32).tobytes()
