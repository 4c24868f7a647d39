"""Typed messages of probeless. Importing this package registers every message family.

Families: header (core/*), diagnostics, sensor, geometry, mesh, lighting. See
:mod:`probeless.messages.base` for the machinery and :func:`registry` for all type names.
"""

from __future__ import annotations

from probeless.messages.base import (
                                     ArraySpec,
                                     FieldSpec,
                                     Message,
                                     Struct,
                                     array,
                                     describe,
                                     lookup,
                                     message,
                                     registry,
                                     schema_of,
)
from probeless.messages.diagnostics import InputCounters, NodeStatus, StageTiming
from probeless.messages.geometry import Floorplan, PoseStamped
from probeless.messages.header import Clock, Header, Tick
from probeless.messages.lighting import BrightnessDelta, Cubemap, CubemapLevel, SHCoefficients
from probeless.messages.mesh import HdrPointCloud, PointCloud, TriangleMesh
from probeless.messages.sensor import CameraInfo, DepthImage, Image, Imu

__all__ = [
    # machinery
    "ArraySpec", "FieldSpec", "Message", "Struct", "array", "describe", "lookup", "message",
    "registry", "schema_of",
    # header / core
    "Header", "Tick", "Clock",
    # diagnostics
    "NodeStatus", "StageTiming", "InputCounters",
    # sensor
    "Image", "DepthImage", "CameraInfo", "Imu",
    # geometry
    "PoseStamped", "Floorplan",
    # mesh
    "PointCloud", "HdrPointCloud", "TriangleMesh",
    # lighting
    "Cubemap", "CubemapLevel", "SHCoefficients", "BrightnessDelta",
]
