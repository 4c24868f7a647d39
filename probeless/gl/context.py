"""The headless OpenGL context: creation on EGL (a hardware device when there is one), and making it current.

EGL may enumerate several devices: Mesa's software rasteriser (llvmpipe) and, on a machine with an NVIDIA (or
other) GPU and its driver, the hardware device. :func:`create_context` takes the first hardware device, else the
software one, so a user with a GPU gets it without editing code. ``PROBELESS_GL_DEVICE`` overrides the choice:
an EGL device index, ``software`` (the first software device) or ``auto`` (the default).
"""

from __future__ import annotations

import functools
import os
import re

import moderngl

from probeless.errors import DeviceError

GL_TEXTURE_CUBE_MAP_SEAMLESS = 0x884F
SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swrast", "swiftshader")
MAX_DEVICES = 16

_chosen: dict[tuple[int, str], int] = {}  # (GL version, choice) -> EGL device index chosen in this process


def is_software(ctx: moderngl.Context) -> bool:
    """Whether the context renders on the CPU (Mesa llvmpipe and the like)."""
    return any(s in ctx.info["GL_RENDERER"].lower() for s in SOFTWARE_RENDERERS)


def device_name(ctx: moderngl.Context) -> str:
    """``vendor renderer`` of a context, e.g. ``NVIDIA Corporation NVIDIA H200/PCIe/SSE2``."""
    return f"{ctx.info['GL_VENDOR']} {ctx.info['GL_RENDERER']}"


def _open(index: int, require: int) -> moderngl.Context:
    return moderngl.create_standalone_context(backend="egl", require=require, device_index=index)


def _choice() -> str:
    value = os.environ.get("PROBELESS_GL_DEVICE", "auto").strip().lower() or "auto"
    if value not in ("auto", "software") and not value.isdigit():
        raise DeviceError(f"PROBELESS_GL_DEVICE={value!r}: give an EGL device index, 'software' or 'auto'")
    return value


def pick_device(open_device, choice: str = "auto", max_devices: int = MAX_DEVICES):
    """(index, context) of the device to use. ``open_device(i)`` opens EGL device i and raises past the last one;
    ``choice``: ``auto`` (the first hardware device, else device 0), ``software`` or an index. The contexts
    opened while looking are released, except the one returned."""
    if choice.isdigit():
        return int(choice), open_device(int(choice))
    first = open_device(0)
    if is_software(first) == (choice == "software"):
        return 0, first
    for index in range(1, max_devices):
        try:
            ctx = open_device(index)
        except Exception as exc:  # past the last device (glcontext: "requested device index ...")
            if re.search(r"device", str(exc), re.I):
                break
            raise
        if is_software(ctx) == (choice == "software"):
            first.release()
            return index, ctx
        ctx.release()
    return 0, first


def create_context(require: int = 430) -> moderngl.Context:
    """A standalone headless (EGL) OpenGL context of at least version ``require`` (430: compute shaders), on the
    device the module doc describes (looked for once per process)."""
    choice = _choice()
    try:
        if (require, choice) in _chosen:
            return _open(_chosen[require, choice], require)
        index, ctx = pick_device(lambda i: _open(i, require), choice)
        _chosen[require, choice] = index
        return ctx
    except DeviceError:
        raise
    except Exception as exc:  # moderngl/glcontext raise plain Exception subclasses
        raise DeviceError(f"OpenGL: cannot create a headless EGL context with GL >= {require / 100:.2f}: "
                          f"{exc}") from exc


def current_context(method):
    """Decorator: make ``self.ctx`` current before the method runs. Several GL objects owning contexts
    may share a thread; the context stays current afterwards so the caller's GL calls keep working."""

    @functools.wraps(method)
    def wrapper(self, *args, **kwargs):
        self.ctx.__enter__()
        return method(self, *args, **kwargs)

    return wrapper
