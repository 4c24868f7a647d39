"""OpenGL plumbing shared by every GPU package (bottom layer: moderngl + numpy, no other probeless import
but ``errors``).

* :mod:`~probeless.gl.context`: the headless EGL context and the decorator that makes it current;
* :mod:`~probeless.gl.programs`: shader loading (``#define``, ``#include``, ``#line``), uniforms, matrix bytes;
* :mod:`~probeless.gl.textures`: image and cubemap uploads, float render targets, the GPU cube-face copy.

Shader files: ``shaders/`` holds programs several packages use (``fullscreen.vert.glsl``, the
one-triangle full-screen vertex shader; ``textured_mesh.vert.glsl``; ``cubecopy.comp.glsl``), named
with ``load_program(..., vertex=NAME)`` or loaded by name; ``glsl/`` is the ``#include``
library (``fresnel.glsl``, ``equirect.glsl``). Camera matrices are maths: :mod:`probeless.geom.projection`.
"""
