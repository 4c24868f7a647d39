"""The synthetic scene description (what a scene YAML file holds), as frozen dataclasses.

World frame: metres, z up, floor at z = 0. Cameras use the OpenCV convention (x right, y down,
z forward); poses are ``world_from_camera``. Read a file with :func:`probeless.scene.parse.load_scene`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from probeless.scene.effects_spec import Given, SensorEffects


@dataclass(frozen=True)
class Material:
    """A plain linear colour, or a tiled texture (linear albedo = colour x texture)."""

    color: np.ndarray            # (3,) linear albedo [0..1]
    texture: Path | None = None  # image file, sRGB-encoded (converted to linear when loaded)
    tile_m: float = 1.0          # texture repeat length [m]


@dataclass(frozen=True)
class Window:
    """An emissive rectangle on wall ``wall`` (the edge from vertex ``wall`` to ``wall + 1``)."""

    wall: int
    center: np.ndarray    # (along the wall from its first vertex, height above the floor) [m]
    size: np.ndarray      # (width, height) [m]
    radiance: np.ndarray  # (3,) emitted radiance [linear]


@dataclass(frozen=True)
class Light:
    """A ceiling panel facing down, switched over time by ``schedule``."""

    position: np.ndarray            # (3,) panel centre [m, world]
    size: np.ndarray                # (x extent, y extent) [m]
    radiance: np.ndarray            # (3,) emitted radiance when on [linear]
    schedule: tuple[tuple[float, bool], ...]  # (t [s], on) with increasing t; before the first entry: its state

    def is_on(self, t: float) -> bool:
        """Whether the light is on at scene time ``t`` [s]."""
        state = self.schedule[0][1]
        for when, on in self.schedule:
            if when <= t:
                state = on
        return state


@dataclass(frozen=True)
class Furniture:
    """A box or a mesh standing in the room (real geometry near the virtual content)."""

    kind: str                      # "box" | "mesh"
    color: np.ndarray              # (3,) linear albedo [0..1]
    center: np.ndarray | None = None   # box: centre (3,) [m, world]
    size: np.ndarray | None = None     # box: full extents (3,) [m]
    path: Path | None = None           # mesh: OBJ file
    position: np.ndarray | None = None  # mesh: where the mesh origin goes (3,) [m, world]
    scale: float = 1.0                 # mesh: uniform scale [m per file unit]
    yaw_deg: float = 0.0               # mesh: rotation about world z after uprighting [deg]
    up: str = "y"                      # mesh: the file's up axis, "y" or "z"


@dataclass(frozen=True)
class VirtualObject:
    """Where an environment map is wanted (and evaluated against ground truth)."""

    id: str
    position: np.ndarray  # (3,) centre [m, world]
    radius: float         # bounding sphere radius [m]
    material: dict | None = None  # e.g. {type: mirror} or {type: diffuse, albedo: [..]}, passed through untouched
    mesh: str = "sphere"          # what the compositor draws (a built-in shape name or a mesh file)


@dataclass(frozen=True)
class RgbdCamera:
    """The RGB-D camera (colour and depth registered, same intrinsics)."""

    width: int
    height: int
    K: np.ndarray          # (3, 3) pinhole camera matrix [px]
    fps: float             # frame rate [Hz]
    depth_noise_m: float   # standard deviation of additive Gaussian depth noise [m]
    depth_max_m: float     # depth beyond this is invalid (0) [m]
    exposure: float        # linear radiance -> display value multiplier before sRGB encoding [-]


@dataclass(frozen=True)
class FisheyeCamera:
    """The upward fisheye camera: an ideal model of ``fov_deg`` filling the image circle."""

    model: str             # "omnidir" | "kannala_brandt"
    width: int
    height: int
    fov_deg: float         # full field of view [deg]
    fps: float             # frame rate [Hz]
    time_offset_s: float   # first fisheye frame time relative to the first RGB-D frame [s]
    exposure: float        # as RgbdCamera.exposure [-]
    xi: float = 1.0        # omnidir sphere offset [-]


@dataclass(frozen=True)
class Keyframe:
    """One trajectory keyframe of the RGB-D camera."""

    t: float               # scene time [s]
    position: np.ndarray   # camera centre (3,) [m, world]
    look_at: np.ndarray    # point the optical axis passes through (3,) [m, world]


@dataclass(frozen=True)
class Scene:
    """A parsed, validated scene file."""

    name: str
    path: Path                       # the scene file (relative paths are resolved against its folder)
    floorplan: np.ndarray            # (N, 2) counter-clockwise floor polygon [m, world]
    ceiling_height: float            # [m]
    walls: Material
    floor: Material
    ceiling: Material
    windows: tuple[Window, ...]
    lights: tuple[Light, ...]
    furniture: tuple[Furniture, ...]
    virtual_objects: tuple[VirtualObject, ...]
    rgbd: RgbdCamera
    fisheye: FisheyeCamera
    fisheye_from_rgbd: np.ndarray    # (4, 4) rigid transform, p_fisheye = T @ p_rgbd
    keyframes: tuple[Keyframe, ...]
    sensor_effects: SensorEffects | None = None  # None = ideal cameras (probeless.scene.effects_spec)
    given: Given | None = None                   # None = the pipeline is told the truth

    @property
    def duration(self) -> float:
        """Trajectory length [s] (the last keyframe's time)."""
        return self.keyframes[-1].t
