"""Log probeless messages to a Rerun recording stream, keeping the state the entity tree needs.

Entity tree (timeline ``stamp``: every message is logged at its ``header.stamp_ns``, as a timestamp):

* ``/world``: static ``ViewCoordinates.RIGHT_HAND_Z_UP`` (the world frame is z-up, metres).
* PoseStamped in ``world``: ``/world/<topic>`` Transform3D + TransformAxes3D(0.2). Other PoseStamped
  (extrinsics such as ``rig/fisheye_from_rgbd``): ``/<topic>`` AnyValues (frames, translation, quaternion, 4x4).
* Cameras: ``/world/camera/<frame>`` Transform3D, the latest world pose whose ``child_frame_id`` is the frame;
  an estimate wins over ground truth (a topic with a ``gt`` segment), which is used only until the first
  estimate of that frame. The pose maps the optical frame (x right, y down, z forward) to the world.
  Pinhole CameraInfo: Pinhole at ``/world/camera/<frame>/image``; the camera's own Image and DepthImage
  (published by the node that publishes the CameraInfo, with its size) at ``/world/camera/<frame>/image/<topic>``
  (DepthImage ``meter`` = depth_scale), so they appear in the frustum and depth back-projects. Other models:
  the frustum as LineStrips3D at ``/world/camera/<frame>/frustum`` (the image border unprojected with the
  camera model, rays of 0.3 m) and the images at ``/<topic>``. Images of a frame without CameraInfo, or
  of another node (``compositor/image``), and all other Image topics: ``/<topic>``; float images through sRGB.
* PointCloud, HdrPointCloud (Reinhard + sRGB), TriangleMesh, Floorplan (LineStrips3D: floor, ceiling, vertical
  edges): ``/world/<topic>``. A TriangleMesh with uvs is textured with the latest Image of its atlas topic
  (``X/mesh`` pairs with ``X/atlas``; ``pairs`` names others); a new atlas re-logs the mesh at most every
  ``texture_period_s`` of stamps. uvs are OpenGL (v up) and flipped to Rerun's top-left origin.
* Cubemap: ``/<topic>/<object_id>`` the cross net as an Image (linear: Reinhard then sRGB 8-bit), and
  ``/world/objects/<object_id>`` Points3D at its position.
* SHCoefficients: ``/<topic>/<object_id>`` Tensor (k x RGB) + Scalars of the DC term (series r, g, b).
* BrightnessDelta: ``/<topic>`` Scalars (r, g, b), only when sampled.
* NodeStatus: ``/timings/<node_id>/<stage>`` Scalars(mean_ms), ``/memory/<node_id>`` Scalars(RSS MiB).
  Diagnostics are stamped with the host clock while a synthetic scene's data starts at 0: when the two are more
  than ``CLOCK_SPLIT_S`` apart, a NodeStatus is logged at the latest data stamp seen, so the timings sit beside
  the frames they were measured on instead of 56 years later on the timeline.
* TrackingState: ``/<topic>`` TextLog (WARN unless ok).
* Anything else is skipped, counted per topic in ``skipped`` (``reasons`` says why).
"""

from __future__ import annotations

from collections import defaultdict
from typing import Any, Callable

import numpy as np
import rerun as rr

from probeless.viz import rerun_map as m
from probeless.viz.blueprint import room_eye
from probeless.viz.rerun_map import Log, camera_path, entity

TIMELINE = "stamp"
CLOCK_SPLIT_S = 60.0


def _node(topic: str) -> str:
    return topic.split("/", 1)[0]


def _info_key(info: Any) -> tuple:
    return (info.model, info.width, info.height, info.K.tobytes(), info.D.tobytes(), info.xi,
            info.ocam_poly.tobytes(), info.ocam_invpoly.tobytes(), info.ocam_affine.tobytes(),
            info.ocam_center.tobytes())


class RerunLogger:
    """Logs each message of a topic as its Rerun archetypes on ``stream`` (see the module doc)."""

    def __init__(self, stream: Any, *, pairs: dict[str, str] | None = None, texture_period_s: float = 1.0,
                 blueprint: Callable[..., Any] | None = None, jpeg_quality: int = 0):
        self.stream = stream
        self.jpeg_quality = jpeg_quality    # > 0: 8-bit grey/RGB images go out as JPEG (rerun_map.image)
        self.blueprint = blueprint          # blueprint(eye) re-sent when the first floorplan shows the room
        self._room_seen = False
        self.pairs = dict(pairs or {})                      # mesh topic -> atlas topic
        self.texture_period_ns = int(texture_period_s * 1e9)
        self.logged: dict[str, int] = defaultdict(int)
        self.skipped: dict[str, int] = defaultdict(int)
        self.reasons: dict[str, str] = {}
        self.archetypes: dict[str, set[str]] = defaultdict(set)  # topic -> archetype names logged
        self.infos: dict[str, tuple[str, Any]] = {}        # frame -> (topic, CameraInfo)
        self._info_logged: dict[str, tuple] = {}
        self._frustums: dict[tuple, Any] = {}
        self.estimated: set[str] = set()                   # frames with an estimated pose seen
        self.atlases: dict[str, tuple[int, np.ndarray]] = {}  # atlas topic -> (stamp, texture)
        self.meshes: dict[str, Any] = {}
        self._textured_at: dict[str, int] = {}
        self._static: set[tuple[str, str]] = set()
        self.data_stamp_ns: int | None = None              # latest stamp of a non-diagnostics message
        self._handlers = {
            "geometry/PoseStamped": self._pose, "sensor/CameraInfo": self._camera_info,
            "sensor/Image": self._image, "sensor/DepthImage": self._depth,
            "mesh/PointCloud": lambda t, msg: m.point_cloud(t, msg),
            "mesh/HdrPointCloud": lambda t, msg: m.hdr_point_cloud(t, msg),
            "mesh/TriangleMesh": self._mesh, "geometry/Floorplan": self._floorplan,
            "lighting/Cubemap": lambda t, msg: m.cubemap(t, msg),
            "lighting/SHCoefficients": lambda t, msg: m.sh_coefficients(t, msg),
            "lighting/BrightnessDelta": self._delta,
            "diagnostics/NodeStatus": lambda t, msg: m.node_status(msg),
            "diagnostics/TrackingState": lambda t, msg: m.tracking_state(t, msg),
        }
        stream.log("/world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)

    def atlas_of(self, mesh_topic: str) -> str:
        """The atlas topic paired with a mesh topic: ``pairs``, else ``X/mesh`` -> ``X/atlas``."""
        if mesh_topic in self.pairs:
            return self.pairs[mesh_topic]
        head, _, last = mesh_topic.rpartition("/")
        return f"{head}/atlas" if last == "mesh" and head else ""

    def log(self, topic: str, msg: Any) -> bool:
        """Log one message received on ``topic``; False when it was skipped (counted in ``skipped``)."""
        handler = self._handlers.get(getattr(msg, "TYPE_NAME", ""))
        if handler is None:
            return self.skip(topic, f"{getattr(msg, 'TYPE_NAME', type(msg).__name__)} has no Rerun mapping")
        entries = handler(topic, msg)
        if entries is None:
            return self.skip(topic, "not sampled")
        self.stream.set_time(TIMELINE, timestamp=np.datetime64(self._stamp_of(msg), "ns"))
        for e in entries:
            self._emit(topic, e)
        self.logged[topic] += 1
        return True

    def _stamp_of(self, msg: Any) -> int:
        """The timeline value of a message: its stamp, but diagnostics on another clock go to the data's."""
        stamp = int(msg.header.stamp_ns)
        if msg.TYPE_NAME != "diagnostics/NodeStatus":
            self.data_stamp_ns = stamp if self.data_stamp_ns is None else max(self.data_stamp_ns, stamp)
            return stamp
        if self.data_stamp_ns is not None and abs(stamp - self.data_stamp_ns) > CLOCK_SPLIT_S * 1e9:
            return self.data_stamp_ns
        return stamp

    def handles(self, type_name: str) -> bool:
        """Whether messages of ``type_name`` have a mapping (others are skipped without decoding them)."""
        return type_name in self._handlers

    def skip(self, topic: str, reason: str) -> bool:
        """Count a message of ``topic`` as skipped, for ``reason``."""
        self.skipped[topic] += 1
        self.reasons.setdefault(topic, reason)
        return False

    def _emit(self, topic: str, e: Log) -> None:
        name = type(e.archetype).__name__
        if e.static:
            if (e.path, name) in self._static:
                return
            self._static.add((e.path, name))
        self.archetypes[topic].add(name)
        self.stream.log(e.path, e.archetype, static=e.static)

    # -- handlers: (topic, msg) -> entries, None = skip --------------------------------------------

    def _pose(self, topic: str, msg: Any) -> list[Log]:
        if msg.header.frame_id != "world":
            return m.frame_pose(topic, msg)
        out = m.world_pose(topic, msg)
        frame, gt = msg.child_frame_id, m.is_ground_truth(topic)
        if not gt:
            self.estimated.add(frame)
        if not gt or frame not in self.estimated:
            out.append(Log(camera_path(frame), m.transform(msg.target_from_source)))
        return out

    def _camera_info(self, topic: str, info: Any) -> list[Log]:
        frame = info.header.frame_id
        self.infos[frame] = (topic, info)
        key = _info_key(info)
        if self._info_logged.get(frame) == key:
            return []
        self._info_logged[frame] = key
        if info.model == "pinhole":
            return [Log(camera_path(frame) + "/image", m.pinhole(info))]
        if key not in self._frustums:
            if len(self._frustums) > 8:
                self._frustums.clear()
            self._frustums[key] = m.frustum(info)
        return [Log(camera_path(frame) + "/frustum", self._frustums[key])]

    def image_path(self, topic: str, msg: Any) -> str:
        """Where an Image or DepthImage of ``topic`` goes: inside its pinhole camera, or ``/<topic>``."""
        topic_info = self.infos.get(msg.header.frame_id)
        if topic_info is not None:
            info_topic, info = topic_info
            if (info.model == "pinhole" and _node(info_topic) == _node(topic)
                    and msg.data.shape[:2] == (info.height, info.width)):
                return camera_path(msg.header.frame_id) + "/image" + entity(topic)
        return entity(topic)

    def _image(self, topic: str, msg: Any) -> list[Log]:
        path = self.image_path(topic, msg)
        out = [Log(path, m.image(msg, opacity=1.0 if path.startswith("/world/") else None,
                                 jpeg_quality=self.jpeg_quality))]
        meshes = [t for t in self.meshes if self.atlas_of(t) == topic]
        if meshes or topic in self.pairs.values() or topic.endswith("/atlas"):
            stamp = msg.header.stamp_ns
            self.atlases[topic] = (stamp, m.texture_pixels(msg))
            for t in meshes:
                if abs(stamp - self._textured_at.get(t, -2**62)) >= self.texture_period_ns:
                    out += self._textured_mesh(t, self.meshes[t])
        return out

    def _depth(self, topic: str, msg: Any) -> list[Log]:
        return [Log(self.image_path(topic, msg), m.depth(msg))]

    def _floorplan(self, topic: str, msg: Any) -> list[Log]:
        if self.blueprint is not None and not self._room_seen:   # aim the 3D view at the room, once
            self._room_seen = True
            self.stream.send_blueprint(self.blueprint(room_eye(msg.vertices, msg.ceiling_height)))
        return m.floorplan(topic, msg)

    def _mesh(self, topic: str, msg: Any) -> list[Log]:
        self.meshes[topic] = msg
        return self._textured_mesh(topic, msg)

    def _textured_mesh(self, topic: str, msg: Any) -> list[Log]:
        atlas = self.atlases.get(self.atlas_of(topic)) if len(msg.uvs) else None
        if atlas is not None:
            self._textured_at[topic] = atlas[0]
        return [Log(entity("world", topic), m.mesh(msg, None if atlas is None else atlas[1]))]

    def _delta(self, topic: str, msg: Any) -> list[Log] | None:
        return m.brightness_delta(topic, msg) or None

    def summary_line(self) -> str:
        """``N messages logged on T topics {topic: n, ...}; S skipped {topic: n (reason), ...}``."""
        logged = ", ".join(f"{t}: {n}" for t, n in sorted(self.logged.items()))
        skipped = ", ".join(f"{t}: {n} ({self.reasons.get(t, '')})" for t, n in sorted(self.skipped.items()))
        return (f"{sum(self.logged.values())} messages logged on {len(self.logged)} topics {{{logged}}}; "
                f"{sum(self.skipped.values())} skipped {{{skipped}}}")
