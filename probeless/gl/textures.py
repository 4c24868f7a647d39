"""Texture uploads, float render targets and the GPU copy of a face into a cube texture.

Image convention: an (H, W) or (H, W, C) numpy image (C <= 4) becomes a W x H texture whose row 0
is image row 0 (``t = (row + 0.5) / H``); read-backs of a framebuffer come back in the same order,
so arrays go up and come down without flips. uint8 becomes a normalised texture (0..1 in GLSL,
moderngl dtype ``f1``), float16 ``f2``, every other dtype float32 ``f4``.

Filters: ``"nearest"``, ``"linear"`` (bilinear) or ``"trilinear"`` (bilinear within and linear
between mip levels; the mip chain is rebuilt after each upload).
"""

from __future__ import annotations

import moderngl
import numpy as np

from probeless.errors import ProbelessError

GL_RGBA32F, GL_R32F = 0x8814, 0x822E
FILTERS = {"nearest": (moderngl.NEAREST, moderngl.NEAREST), "linear": (moderngl.LINEAR, moderngl.LINEAR),
           "trilinear": (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)}


def gl_dtype(image: np.ndarray) -> str:
    """moderngl texture dtype of an array: uint8 -> f1 (normalised), float16 -> f2, else f4."""
    return {np.dtype(np.uint8): "f1", np.dtype(np.float16): "f2"}.get(np.asarray(image).dtype, "f4")


def texture_bytes(image: np.ndarray) -> tuple[bytes, str]:
    """(bytes, moderngl dtype) of an image: uint8 and float16 as they are, anything else as float32."""
    dtype = gl_dtype(image)
    a = np.ascontiguousarray(image)
    return (a if dtype != "f4" else a.astype(np.float32, copy=False)).tobytes(), dtype


def _set_sampling(tex, filter: str, repeat: bool | tuple[bool, bool], max_mip_level: int | None) -> None:
    if filter not in FILTERS:
        raise ProbelessError(f"texture filter must be one of {', '.join(FILTERS)}, got {filter!r}")
    tex.filter = FILTERS[filter]
    tex.repeat_x, tex.repeat_y = (repeat, repeat) if isinstance(repeat, bool) else repeat
    if filter == "trilinear":
        tex.build_mipmaps(0, 1000 if max_mip_level is None else max_mip_level)


def upload_texture(ctx: moderngl.Context, image: np.ndarray, tex: moderngl.Texture | None = None, *,
                   filter: str = "nearest", repeat: bool | tuple[bool, bool] = False,
                   max_mip_level: int | None = None) -> moderngl.Texture:
    """``image`` (H, W) or (H, W, C <= 4) as a 2-D texture (see the module docstring for rows and dtypes).

    ``tex``, when given, is rewritten in place if its size, channels and dtype match, else released
    and replaced. ``repeat``: wrap (True) or clamp (False) in x and y, one bool for both or a pair.
    ``max_mip_level`` caps the mip chain of a ``"trilinear"`` texture (None: down to 1 x 1).
    """
    a = np.asarray(image)
    if a.ndim not in (2, 3) or (a.ndim == 3 and a.shape[2] not in (1, 2, 3, 4)) or 0 in a.shape[:2]:
        raise ProbelessError(f"texture upload: expected an (H, W) or (H, W, C<=4) image, got shape {a.shape}")
    data, dtype = texture_bytes(a)
    size, components = (a.shape[1], a.shape[0]), 1 if a.ndim == 2 else a.shape[2]
    if tex is not None and tex.size == size and tex.components == components and tex.dtype == dtype:
        tex.write(data)
    else:
        if tex is not None:
            tex.release()
        tex = ctx.texture(size, components, data, dtype=dtype)
    _set_sampling(tex, filter, repeat, max_mip_level)
    return tex


def upload_cube(ctx: moderngl.Context, faces: np.ndarray, *, filter: str = "trilinear") -> moderngl.TextureCube:
    """A cube texture of (6, S, S, C) faces uploaded unchanged (face order and rows: :mod:`probeless.geom.cube`)."""
    f = np.asarray(faces)
    if f.ndim != 4 or f.shape[0] != 6 or f.shape[1] != f.shape[2] or f.shape[3] not in (1, 2, 3, 4):
        raise ProbelessError(f"cube upload: expected (6, S, S, C<=4) faces, got shape {f.shape}")
    data, dtype = texture_bytes(f)
    tex = ctx.texture_cube((f.shape[1], f.shape[1]), f.shape[3], data, dtype=dtype)
    tex.filter = FILTERS[filter]
    if filter == "trilinear":
        tex.build_mipmaps()
    return tex


def float_target(ctx: moderngl.Context, width: int, height: int, components: int = 4) -> moderngl.Framebuffer:
    """A framebuffer with one float32 colour texture (R32F / RGBA32F, nearest filtering) and a depth buffer."""
    color = ctx.texture((width, height), components, dtype="f4")
    color.filter = (moderngl.NEAREST, moderngl.NEAREST)
    return ctx.framebuffer([color], ctx.depth_renderbuffer((width, height)))


def copy_to_cube_face(ctx: moderngl.Context, copy_prog, image: moderngl.Texture, cube: moderngl.TextureCube,
                      face: int) -> None:
    """GPU copy of a square float texture into ``face`` of ``cube``.

    ``copy_prog``: ``load_program(ctx, "cubecopy", {"FORMAT": "rgba32f" | "r32f"})`` for the cube's format
    (the shared program in :data:`probeless.gl.programs.SHADER_DIR`).
    """
    size = cube.size[0]
    image.use(0)
    copy_prog["face_image"], copy_prog["face"], copy_prog["size"] = 0, face, size
    cube.bind_to_image(0, read=False, write=True, format=GL_RGBA32F if cube.components == 4 else GL_R32F)
    copy_prog.run((size + 7) // 8, (size + 7) // 8, 1)
    ctx.memory_barrier()
