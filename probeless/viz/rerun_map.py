"""Pure mapping of probeless messages to Rerun archetypes: one message -> a list of :class:`Log` entries.

No recording stream here: :class:`probeless.viz.rerun_logger.RerunLogger` keeps the state (camera
calibrations, the tracking pose per camera, the mesh texture) and logs what these functions return.
The entity tree is documented in :mod:`probeless.viz.rerun_logger`.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import cv2
import numpy as np
import rerun as rr

from probeless.cameras import model_from_info
from probeless.color import quantize8, reinhard, to_srgb8
from probeless.scene.preview import cube_net

AXES_LENGTH = 0.2      # [m] of the axes drawn at every world pose
FRUSTUM_DEPTH = 0.3    # [m] along each ray of a non-pinhole camera's frustum
RGB = ("r", "g", "b")


class Log(NamedTuple):
    """One ``stream.log(path, archetype, static=static)`` call."""

    path: str
    archetype: Any
    static: bool = False


def aligned(a: np.ndarray, dtype: Any = None) -> np.ndarray:
    """``a`` as an aligned C-contiguous array (decoded messages may view unaligned wire buffers, which Rerun's
    Arrow import rejects), copied only when needed."""
    return np.require(a, dtype=dtype, requirements=["A", "C"])


def entity(*parts: str) -> str:
    """An entity path from topic-like parts (``"rig/rgb"`` -> ``/rig/rgb``), each segment escaped."""
    segs = [s for p in parts for s in p.split("/") if s]
    return "/" + "/".join(rr.escape_entity_path_part(s) for s in segs)


def camera_path(frame: str) -> str:
    """Entity of the camera ``frame``: its tracking Transform3D."""
    return entity("world/camera", frame)


def is_ground_truth(topic: str) -> bool:
    """A topic with a ``gt`` path segment carries ground truth."""
    return "gt" in topic.split("/")


# -- poses ----------------------------------------------------------------------------------------

def transform(T: np.ndarray) -> rr.Transform3D:
    """Transform3D of a 4x4 parent_from_child matrix."""
    return rr.Transform3D(translation=aligned(T[:3, 3], np.float64), mat3x3=aligned(T[:3, :3], np.float64))


def world_pose(topic: str, msg: Any) -> list[Log]:
    """A pose in the world frame: its transform and axes at ``/world/<topic>``."""
    path = entity("world", topic)
    return [Log(path, transform(msg.target_from_source)), Log(path, rr.TransformAxes3D(AXES_LENGTH))]


def frame_pose(topic: str, msg: Any) -> list[Log]:
    """A pose between two non-world frames (an extrinsic): its values at ``/<topic>``."""
    return [Log(entity(topic), rr.AnyValues(
        target_frame=msg.header.frame_id, source_frame=msg.child_frame_id,
        translation=msg.translation.tolist(), quaternion_xyzw=msg.quaternion.tolist(),
        target_from_source=msg.target_from_source.reshape(-1).tolist()))]


# -- cameras and images ---------------------------------------------------------------------------

def pinhole(info: Any) -> rr.Pinhole:
    """Pinhole of a CameraInfo's K and size (distortion ignored); Rerun's default camera axes are the
    optical frame's (x right, y down, z forward)."""
    return rr.Pinhole(image_from_camera=aligned(info.K, np.float64), resolution=[info.width, info.height],
                      camera_xyz=rr.ViewCoordinates.RDF)


def border_pixels(width: int, height: int, per_side: int = 16) -> np.ndarray:
    """(4 * per_side, 2) pixels around the image area's edge [-0.5, W - 0.5] x [-0.5, H - 0.5], a closed loop
    in order (corners first of each side)."""
    t = np.arange(per_side) / per_side
    x0, x1, y0, y1 = -0.5, width - 0.5, -0.5, height - 0.5
    top = np.stack([x0 + t * (x1 - x0), np.full_like(t, y0)], 1)
    right = np.stack([np.full_like(t, x1), y0 + t * (y1 - y0)], 1)
    bottom = np.stack([x1 - t * (x1 - x0), np.full_like(t, y1)], 1)
    left = np.stack([np.full_like(t, x0), y1 - t * (y1 - y0)], 1)
    return np.concatenate([top, right, bottom, left])


def frustum_strips(info: Any, depth: float = FRUSTUM_DEPTH, per_side: int = 16) -> list[np.ndarray]:
    """Line strips of a camera's field of view: the image border unprojected with the camera model to rays of
    length ``depth`` (the loop, broken where rays are invalid), and rays from the centre to every 4th border point."""
    model = model_from_info(info)
    rays, valid = model.unproject(border_pixels(info.width, info.height, per_side))
    ends = rays * depth
    strips: list[np.ndarray] = []
    run: list[np.ndarray] = []
    for p, ok in zip(np.concatenate([ends, ends[:1]]), np.concatenate([valid, valid[:1]])):
        if ok:
            run.append(p)
        elif run:
            strips.append(np.array(run))
            run = []
    if run:
        strips.append(np.array(run))
    strips = [s for s in strips if len(s) > 1]
    strips += [np.array([np.zeros(3), ends[i]]) for i in range(0, len(ends), 4) if valid[i]]
    return strips


def frustum(info: Any) -> rr.LineStrips3D:
    """LineStrips3D of :func:`frustum_strips` (for cameras Rerun's Pinhole cannot draw)."""
    return rr.LineStrips3D(frustum_strips(info), radii=0.003)


_COLOR_MODELS = {1: "L", 3: "RGB", 4: "RGBA"}


def display_pixels(msg: Any) -> tuple[np.ndarray, str]:
    """(pixels, Rerun colour model) of an Image: integer encodings as they are, linear floats through sRGB."""
    data, enc = msg.data, msg.encoding
    if data.dtype.kind == "f":
        data = data.astype(np.float32)
        out = to_srgb8(data)
        if data.shape[2] == 4:
            out[..., 3] = quantize8(data[..., 3])
        data = out
    model = "BGR" if enc == "bgr8" else "BGRA" if enc == "bgra8" else _COLOR_MODELS[data.shape[2]]
    return aligned(data[..., 0] if data.shape[2] == 1 else data), model


def image(msg: Any, opacity: float | None = None, jpeg_quality: int = 0) -> rr.Image | rr.EncodedImage:
    """Image archetype of a probeless Image (see :func:`display_pixels`); ``opacity`` 1 keeps a camera's image
    opaque over its depth image (the viewer otherwise blends layered images). ``jpeg_quality`` > 0 sends 8-bit
    grey and RGB images as JPEG (an EncodedImage: a tenth of the bytes for a viewer across a network)."""
    pixels, model = display_pixels(msg)
    if jpeg_quality > 0 and pixels.dtype == np.uint8 and model in ("L", "RGB", "BGR"):
        bgr = pixels[..., ::-1] if model == "RGB" else pixels       # OpenCV writes BGR (and grey) JPEGs
        ok, jpeg = cv2.imencode(".jpg", np.ascontiguousarray(bgr), [cv2.IMWRITE_JPEG_QUALITY, jpeg_quality])
        if ok:
            return rr.EncodedImage(contents=jpeg.tobytes(), media_type="image/jpeg", opacity=opacity)
    return rr.Image(pixels, color_model=model, opacity=opacity)


def texture_pixels(msg: Any) -> np.ndarray:
    """An Image as an RGB(A) uint8 texture (BGR reordered)."""
    pixels, model = display_pixels(msg)
    if model.startswith("BGR"):
        pixels = pixels[..., [2, 1, 0, 3][:pixels.shape[2]]]
    if pixels.dtype != np.uint8:
        pixels = (pixels >> 8).astype(np.uint8)
    return pixels if pixels.ndim == 3 else np.repeat(pixels[..., None], 3, axis=2)


def depth(msg: Any) -> rr.DepthImage:
    """DepthImage with ``meter`` = the message's depth units per metre."""
    return rr.DepthImage(aligned(msg.data), meter=float(msg.depth_scale))


# -- 3D data --------------------------------------------------------------------------------------

def colors8(colors: np.ndarray) -> np.ndarray:
    """uint8 sRGB colours as they are; linear float colours through the sRGB curve."""
    return aligned(colors) if colors.dtype == np.uint8 else to_srgb8(colors)


def point_cloud(topic: str, msg: Any) -> list[Log]:
    """Points3D at ``/world/<topic>`` (positions in the message's frame, taken as world)."""
    return [Log(entity("world", topic), rr.Points3D(aligned(msg.points), colors=colors8(msg.colors), radii=0.01))]


def hdr_point_cloud(topic: str, msg: Any) -> list[Log]:
    """Points3D of an HdrPointCloud, radiance Reinhard tone-mapped then sRGB for display."""
    colors = to_srgb8(reinhard(msg.radiance))
    return [Log(entity("world", topic), rr.Points3D(aligned(msg.points), colors=colors, radii=0.01))]


def texcoords(uvs: np.ndarray) -> np.ndarray:
    """OpenGL uvs (v up, origin bottom-left) -> Rerun texcoords (origin top-left, v down)."""
    return np.stack([uvs[:, 0], 1.0 - uvs[:, 1]], axis=1).astype(np.float32)


def mesh(msg: Any, texture: np.ndarray | None = None) -> rr.Mesh3D:
    """Mesh3D of a TriangleMesh; textured with ``texture`` (RGB(A) uint8) when the mesh has uvs."""
    kw: dict[str, Any] = {}
    if len(msg.vertex_normals):
        kw["vertex_normals"] = aligned(msg.vertex_normals)
    if len(msg.vertex_colors):
        kw["vertex_colors"] = colors8(msg.vertex_colors)
    if texture is not None and len(msg.uvs):
        kw["vertex_texcoords"] = texcoords(msg.uvs)
        kw["albedo_texture"] = texture
    # front faces only (counter-clockwise, the TriangleMesh convention): the room prism faces inwards, so from
    # outside its near walls and ceiling vanish and the textured inside shows (a dollhouse view)
    return rr.Mesh3D(vertex_positions=aligned(msg.vertices), triangle_indices=aligned(msg.triangles, np.uint32),
                     face_rendering=rr.components.MeshFaceRendering.Front, **kw)


def floorplan(topic: str, msg: Any) -> list[Log]:
    """LineStrips3D of the room: the floor and ceiling polygons (closed) and the vertical edges."""
    xy = np.asarray(msg.vertices, np.float64)
    floor = np.column_stack([xy, np.zeros(len(xy))])
    ceil = np.column_stack([xy, np.full(len(xy), msg.ceiling_height)])
    edges = [np.array([a, b]) for a, b in zip(floor, ceil)]
    strips = [np.vstack([floor, floor[:1]]), np.vstack([ceil, ceil[:1]])] + edges
    return [Log(entity("world", topic), rr.LineStrips3D(strips, radii=0.01))]


# -- lighting and diagnostics ---------------------------------------------------------------------

def cubemap_net(msg: Any) -> np.ndarray:
    """The horizontal-cross net of a Cubemap's faces as uint8: linear float -> Reinhard -> sRGB; display-referred
    float -> 8-bit codes; uint8 as is."""
    faces = msg.faces
    if faces.dtype != np.uint8:
        f = faces.astype(np.float32)
        faces = to_srgb8(reinhard(f)) if msg.linear else quantize8(f)
    return cube_net(faces)


def cubemap(topic: str, msg: Any) -> list[Log]:
    """The net at ``/<topic>/<object_id>``, the map's position at ``/world/objects/<object_id>``."""
    net = cubemap_net(msg)
    return [Log(entity(topic, msg.object_id), rr.Image(net, color_model=_COLOR_MODELS[net.shape[2]])),
            Log(entity("world/objects", msg.object_id), rr.Points3D(aligned(msg.position, np.float64)[None], radii=0.05,
                                                                    labels=[msg.object_id]))]


def sh_coefficients(topic: str, msg: Any) -> list[Log]:
    """Tensor of the (k, RGB) coefficients and Scalars of the DC term at ``/<topic>/<object_id>``."""
    path = entity(topic, msg.object_id)
    c = aligned(msg.coeffs, np.float64)
    return [Log(path, rr.Tensor(c, dim_names=["k", "rgb"])), Log(path, rr.Scalars(c[0])),
            Log(path, rr.SeriesLines(names=list(RGB)), static=True)]


def brightness_delta(topic: str, msg: Any) -> list[Log]:
    """Scalars of the RGB delta at ``/<topic>``; nothing when the frame was not sampled."""
    if not msg.sampled:
        return []
    path = entity(topic)
    return [Log(path, rr.Scalars(aligned(msg.delta, np.float64))),
            Log(path, rr.SeriesLines(names=list(RGB)), static=True)]


def node_status(msg: Any) -> list[Log]:
    """Scalars of each stage's mean time at ``/timings/<node_id>/<stage>`` and of the RSS [MiB] at
    ``/memory/<node_id>``."""
    out = [Log(entity("timings", msg.node_id) + "/" + rr.escape_entity_path_part(t.name), rr.Scalars(t.mean_ms))
           for t in msg.timings]
    out.append(Log(entity("memory", msg.node_id), rr.Scalars(msg.rss_bytes / 2**20)))
    return out


def tracking_state(topic: str, msg: Any) -> list[Log]:
    """TextLog of the state (and reason) at ``/<topic>``, level WARN unless ``ok``."""
    text = msg.state + (f": {msg.reason}" if msg.reason else "")
    return [Log(entity(topic), rr.TextLog(text, level="INFO" if msg.state == "ok" else "WARN"))]
