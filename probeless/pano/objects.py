"""The 360° IBL scene's virtual objects (paper 002, §6): five material combinations in an arc.

Object specs are dicts read by :func:`probeless.ibl.objects.object_from_dict`. Mesh paths that do
not exist relative to the working folder are looked up in the repository, so the default teapot
(``launch/scenes/meshes/teapot.obj``) works from anywhere.
"""

from __future__ import annotations

from probeless.paths import repo_path

TEAPOT = "launch/scenes/meshes/teapot.obj"
MONO_SIZE = (1280, 720)  # the paper's single camera view (width, height) [px]

# Five objects, each a different material combination (paper 002, §6), in an arc 2.5 m in front
# of the start view (+x), below eye height.
DEFAULT_OBJECTS = (
    {"id": "mirror_teapot", "mesh": TEAPOT, "position": [2.5, 1.15, -0.45], "radius": 0.32, "yaw_deg": -60,
     "material": {"type": "mirror"}},
    {"id": "gold_sphere", "mesh": "sphere", "position": [2.7, 0.55, -0.1], "radius": 0.22,
     "material": {"type": "metal", "colour": [1.0, 0.78, 0.34], "roughness": 0.1}},
    {"id": "white_teapot", "mesh": TEAPOT, "position": [2.4, 0.0, -0.5], "radius": 0.32, "yaw_deg": -90,
     "material": {"type": "diffuse", "albedo": [0.8, 0.8, 0.8]}},
    {"id": "plastic_sphere", "mesh": "sphere", "position": [2.7, -0.55, -0.1], "radius": 0.22,
     "material": {"type": "mix", "layers": [{"weight": 0.75, "type": "diffuse", "albedo": [0.8, 0.12, 0.1]},
                                            {"weight": 0.25, "type": "metal", "colour": [1, 1, 1],
                                             "roughness": 0.2}]}},
    {"id": "glass_sphere", "mesh": "sphere", "position": [2.5, -1.15, -0.45], "radius": 0.3,
     "material": {"type": "glass", "ior": 1.5}},
)


def resolve_mesh(spec: dict) -> dict:
    """``spec`` with a relative mesh path that is missing here replaced by the repository's file."""
    mesh = spec.get("mesh")
    if isinstance(mesh, str) and mesh != "sphere":
        return {**spec, "mesh": str(repo_path(mesh))}
    return dict(spec)
