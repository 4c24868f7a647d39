"""The headless OpenGL context: creation on EGL, and making it current for a method."""

from __future__ import annotations

import functools

import moderngl

from probeless.errors import DeviceError

GL_TEXTURE_CUBE_MAP_SEAMLESS = 0x884F


def create_context(require: int = 430) -> moderngl.Context:
    """A standalone headless (EGL) OpenGL context of at least version ``require`` (430: compute shaders)."""
    try:
        return moderngl.create_standalone_context(backend="egl", require=require)
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
