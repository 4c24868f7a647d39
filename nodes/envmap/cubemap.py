"""Cubemap renderer node (paper §4.7): an environment map + its SH projection per virtual object.

Renders when a new ``atlas`` arrives (at most ``max_rate_hz``; an atlas arriving sooner is rendered
by a timer once the interval is over): for each object, the textured coarse model, then the
newest dense model (``points`` or ``dense_mesh``) on top without depth testing, with the brightness
changes ``delta`` added to its colours as the texturer adds them to texels out of view: each point gets the
Δ summed since it was last fused (``PointCloud.stamps_ns``; without them, since the model's stamp), so
parts of the model out of view keep up with a light switch when a new model arrives; other objects as flat
spheres when
``draw_objects``. The atlas layout comes from ``floorplan`` + ``atlas_size`` / ``texels_per_m``
exactly as in the texturer (:func:`probeless.coarse.model.make_layout`).

Objects: the ``objects_file`` param (a scene file's ``virtual_objects`` or an objects file:
:mod:`probeless.scene.objects_file`) and the ``object_ids`` / ``object_positions`` params; an ``object_poses``
PoseStamped whose ``child_frame_id`` is an object id moves it (an unknown id adds an object).

Outputs per object ``<id>``: ``envmap/<id>`` (Cubemap, ``linear = False``: camera LDR units,
sRGB-encoded like the fisheye image; uint8 or float16; ``mip_levels - 1`` box-filtered mips with
roughness i / (mip_levels - 1)) and ``sh/<id>`` (SHCoefficients of the map linearised with the
sRGB curve: "linear camera units" = radiance x exposure, clipped at 1 - what a renderer that
re-encodes to the camera's sRGB needs). The same messages go out on ``envmaps`` and ``shs`` too, every
object on one topic (routed by ``object_id``): a consumer wires one input whatever the objects are.
``Cubemap.observed`` marks the texels showing an observed atlas texel or a dense point (when the renderer
reports it). Stamps are the atlas's.

HDR lighting (paper 003's future work with paper 001 §4): an ``atlas`` of a float encoding (``rgbf32``,
``rgbf16``, ``rgbaf32``, ``rgbaf16``; by the message convention float images are linear) is linear radiance in the
camera's linear units (1 = LDR white), e.g. ``hdr_atlas_expander``'s. Such an atlas is drawn unclipped
(:class:`probeless.envmap.cubemap.EnvmapRenderer`, ``linear=True``) and the maps come out as
``envmap/<id>`` ``Cubemap(linear=True)``, float16 whatever ``dtype`` says (clipped at float16's largest value),
mips of the linear map, and ``sh/<id>`` the SH of the linear map (same units: the compositor lights with the
same ``exposure`` as for an LDR map). The dense model on top is then the newest ``hdr_points``
(``mesh/HdrPointCloud``, e.g. ``hdr_expander``'s: its radiance, no Δ - Δ is in LDR units) once one has
arrived, else ``points`` / ``dense_mesh`` with their Δ applied, clipped to LDR white and decoded to linear
(:func:`probeless.hdr.coarse.dense_linear`, as ``probeless eval hdr-envmap``'s ``hdr_coarse`` map). The cube net
written to ``net_dir`` is the linear map clipped at 1 and sRGB-encoded (what the camera would show). A ``uint8``
atlas (the texturer's ``rgba8``) gives exactly the LDR maps above; ``hdr_points`` are then not drawn.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import numpy as np

from probeless.coarse.model import CoarseConfig, make_layout
from probeless.color import linear_to_srgb, srgb_to_linear
from probeless.envmap.cubemap import EnvmapRenderer, prefilter
from probeless.envmap.delta_history import DeltaHistory
from probeless.envmap.objects import (
    move_object,
    node_objects,
    object_ids_problem,
    object_positions_problem,
    write_nets,
)
from probeless.envmap.sh import project_cubemap
from probeless.errors import ProbelessError
from probeless.messages.geometry import Floorplan, PoseStamped
from probeless.messages.header import Header
from probeless.messages.lighting import (
    BrightnessDelta,
    Cubemap,
    CubemapLevel,
    SHCoefficients,
)
from probeless.messages.mesh import HdrPointCloud, PointCloud, TriangleMesh
from probeless.messages.sensor import CameraInfo, Image
from probeless.runtime import Node, param
from probeless.runtime.oncelog import OnceLog
from probeless.scene.objects_file import objects_file_problem

HDR_ATLAS_ENCODINGS = ("rgbf32", "rgbf16", "rgbaf32", "rgbaf16")  # linear radiance (module docstring)
FLOAT16_MAX = float(np.finfo(np.float16).max)


def to_ldr(colors: np.ndarray) -> np.ndarray:
    """Message colours (uint8 sRGB, or float linear 0..1) as camera LDR 0..1 float32."""
    c = np.asarray(colors)
    return c.astype(np.float32) / 255.0 if c.dtype == np.uint8 else linear_to_srgb(c).astype(np.float32)


def _mip_problem(face_size: int, p) -> str | None:
    """face_size's rule against mip_levels (a param check): every mip level has a whole number of texels."""
    step = 1 << (p.mip_levels - 1)
    return f"face_size {face_size} is not divisible by 2^(mip_levels-1) = {step}" if face_size % step else None


class CubemapRenderer(Node):
    """``floorplan`` + ``atlas`` (+ ``points`` | ``dense_mesh``, ``hdr_points``, ``delta``, ``object_poses``)
    -> ``envmap/*``, ``sh/*``."""

    INPUTS = {"floorplan": Floorplan, "atlas": Image, "points": PointCloud, "dense_mesh": TriangleMesh,
              "hdr_points": HdrPointCloud, "delta": BrightnessDelta, "object_poses": PoseStamped,
              # the baseline's inputs, accepted (ignored) so the two nodes swap by their node: line alone
              "fisheye": Image, "fisheye_pose": PoseStamped, "camera_info": CameraInfo}
    IGNORED = ("fisheye", "fisheye_pose", "camera_info")
    OUTPUTS = {"envmap/*": Cubemap, "sh/*": SHCoefficients, "envmaps": Cubemap, "shs": SHCoefficients}

    @dataclass(frozen=True)
    class Params:
        atlas_size: int = param(0, min=0, max=16384, doc="atlas side when texels_per_m is 0 [texels] (as the "
                                                         "texturer's); 0 = the width of the atlas images received")
        texels_per_m: float = param(0.0, min=0.0, max=10000.0,
                                    doc="texel density; 0 = fit atlas_size [texels/m] (as the texturer's)")
        objects_file: str = param("", path="file", must_exist=True, check=objects_file_problem,
                                  doc="scene file (its virtual_objects) or objects file; '' = only the params below")
        object_ids: tuple[str, ...] = param((), check=object_ids_problem,
                                            doc="virtual objects to render an environment map for")
        object_positions: tuple[tuple[float, ...], ...] = param((), check=object_positions_problem,
                                                                doc="[x, y, z] per object id [m, world]")
        face_size: int = param(256, min=4, max=4096, check=_mip_problem,
                               doc="cube face side [texels]; divisible by 2^(mip_levels-1)")
        dense: bool = param(True,
                            doc="render the dense model on top of the coarse one (false: the 'no dense' ablation)")
        splat_m: float = param(0.02, min=0.0, max=1.0,
                               doc="world diameter of a point splat, about the point spacing [m]")
        max_splat_px: float = param(64.0, min=1.0, max=255.0, doc="largest splat [px]")
        draw_objects: bool = param(False, doc="draw the other virtual objects as flat spheres into each map")
        object_radius: float = param(0.1, min=0.0, max=10.0, doc="sphere radius of other objects [m]")
        object_color: tuple[float, ...] = param((0.8, 0.8, 0.8), length=3,
                                                doc="sphere colour of other objects [camera LDR 0..1]")
        mip_levels: int = param(6, min=1, max=12, doc="levels incl. the base; face_size must divide by 2^(levels-1)")
        sh_bands: int = param(5, min=1, max=8, doc="SH bands of the sh/* output (5 = 25 coefficients, the paper's)")
        dtype: str = param("uint8", choices=("uint8", "float16"), doc="face sample type")
        max_rate_hz: float = param(0.0, min=0.0, max=1000.0, doc="render at most this often; 0 = every atlas [Hz]")
        observed: bool = param(True, doc="fill Cubemap.observed (texels showing an observed atlas texel or a dense "
                                         "point): one more render pass per map")
        net_dir: str = param("", doc="write the last map of each object as a cube net, <net_dir>/cubemap_net_<id>.png, "
                                     "at the end (the paper's Figure 9); '' = none")

    def setup(self) -> None:
        p = self.params
        self.objects = node_objects(p.objects_file, p.object_ids, p.object_positions, self.ctx.node_id)
        self.renderer: EnvmapRenderer | None = None
        self.floorplan: Floorplan | None = None
        self.atlas: Image | None = None
        self.history = DeltaHistory()
        self.uploaded_total = np.zeros(3)  # Δ total baked into the uploaded dense colours
        self.dense_msg: PointCloud | TriangleMesh | None = None
        self.hdr_dense: HdrPointCloud | None = None
        self.dense_dirty = False
        self.dense_uploaded: tuple | None = None  # what the renderer holds: _dense_want()'s key
        self.pending = False
        self.last_render_ns: int | None = None
        self.counts: Counter[str] = Counter()
        self.once = OnceLog(self.ctx.log)
        self.last_faces: dict[str, np.ndarray] = {}
        if p.max_rate_hz > 0:
            self.ctx.create_timer(min(0.05, 0.25 / p.max_rate_hz), self._maybe_render, name="render")

    def on_input(self, name: str, msg) -> None:
        if name in self.IGNORED:
            return
        if name == "floorplan":
            self._on_floorplan(msg)
        elif name == "atlas":
            self.atlas, self.pending = msg, True
        elif name in ("points", "dense_mesh"):
            self._set_dense(msg)
        elif name == "hdr_points":
            if self._world_frame(msg):
                self.hdr_dense, self.dense_dirty = msg, True
        elif name == "delta":
            if msg.sampled:
                self.history.add(msg.header.stamp_ns, msg.delta)
        elif name == "object_poses":
            move_object(self.objects, msg, self.counts)
        self._maybe_render()

    def _on_floorplan(self, msg: Floorplan) -> None:
        if self.floorplan is not None and np.array_equal(msg.vertices, self.floorplan.vertices) \
                and msg.ceiling_height == self.floorplan.ceiling_height:
            return
        self.floorplan = msg
        if self.renderer is not None:
            self.renderer.release()
            self.renderer = None  # rebuilt for the new room at the next render

    def _make_renderer(self) -> bool:
        """Build the renderer for the floorplan and the atlas size (param, or the received atlas's width)."""
        p, msg = self.params, self.floorplan
        size = p.atlas_size or self.atlas.data.shape[1]
        try:
            layout = make_layout(msg.vertices, msg.ceiling_height, CoarseConfig(size, p.texels_per_m))
        except ProbelessError as exc:
            self.counts["bad_floorplan"] += 1
            self.once.error("floorplan", f"floorplan rejected: {exc}")
            return False
        self.renderer = EnvmapRenderer(layout)
        self.dense_dirty = self.dense_msg is not None or self.hdr_dense is not None
        self.dense_uploaded = None
        return True

    def _world_frame(self, msg) -> bool:
        if msg.header.frame_id != "world":
            self.once.error("dense_frame", f"dense model in frame '{msg.header.frame_id}', expected 'world': ignored")
            self.counts["dense_wrong_frame"] += 1
            return False
        return True

    def _set_dense(self, msg: PointCloud | TriangleMesh) -> None:
        if not self._world_frame(msg):
            return
        self.dense_msg, self.dense_dirty = msg, True

    def _dense_want(self, hdr: bool) -> tuple | None:
        """Key of the dense model the map needs (None: none): LDR, the HDR cloud, or the LDR model linearised
        with the current Δ (module docstring)."""
        if not hdr:
            return ("ldr",) if self.dense_msg is not None else None
        if self.hdr_dense is not None:
            return ("hdr",)
        return ("linear", *self.history.total().tolist()) if self.dense_msg is not None else None

    def _dense_colors(self) -> np.ndarray:
        """The dense model's LDR colours with the Δ each point has missed since it was last fused, clipped to
        0..1; the Δ total they include is kept in ``uploaded_total`` (later Δ goes in as a uniform)."""
        m = self.dense_msg
        colors = to_ldr(m.colors if isinstance(m, PointCloud) else m.vertex_colors)
        stamps = m.stamps_ns if isinstance(m, PointCloud) and len(m.stamps_ns) else [m.header.stamp_ns]
        self.uploaded_total = self.history.total()
        return np.clip(colors + self.history.since(stamps), 0.0, 1.0)

    def _upload_dense(self, want: tuple) -> None:
        """Hand the dense model ``want`` (:meth:`_dense_want`) to the renderer."""
        self.dense_dirty, self.dense_uploaded = False, want
        m = self.dense_msg
        with self.ctx.timed("upload_dense"):
            if want[0] == "hdr":
                self.renderer.set_dense(self.hdr_dense.points, self.hdr_dense.radiance, linear=True)
                return
            colors = self._dense_colors()
            linear = want[0] == "linear"
            if linear:
                # imported here: probeless.hdr loads numba (about 1.5 s), which LDR maps never need
                from probeless.hdr.coarse import dense_linear

                colors = dense_linear(colors)
            if isinstance(m, PointCloud):  # normals drop points seen from behind (a table's dark sides)
                self.renderer.set_dense(m.points, colors, linear=linear,
                                        normals=m.normals if len(m.normals) else None)
            else:
                self.renderer.set_dense_mesh(m.vertices, m.triangles, colors, linear=linear)

    def _maybe_render(self) -> None:
        if not self.pending or self.floorplan is None or self.atlas is None:
            return
        if self.renderer is None and not self._make_renderer():
            return
        now, rate = self.ctx.now_ns(), self.params.max_rate_hz
        if rate > 0 and self.last_render_ns is not None and now - self.last_render_ns < 1e9 / rate:
            return
        hdr = self.atlas.encoding in HDR_ATLAS_ENCODINGS
        want = self._dense_want(hdr)
        if self.params.dense and want is not None and (self.dense_dirty or want != self.dense_uploaded):
            self._upload_dense(want)
        self.pending, self.last_render_ns = False, now
        try:
            with self.ctx.timed("upload_atlas"):
                self.renderer.set_atlas(self.atlas.data, linear=hdr)
        except ProbelessError as exc:
            self.once.error("atlas", f"atlas rejected: {exc} (give the texturer and this node the same atlas params)")
            self.counts["atlas_rejected"] += 1
            return
        for oid, pos in self.objects.items():
            self._render_object(oid, pos, hdr)

    def _render_object(self, oid: str, pos: np.ndarray, hdr: bool = False) -> None:
        p = self.params
        spheres = [(x, p.object_radius, p.object_color) for o, x in self.objects.items()
                   if o != oid and p.draw_objects]
        # HDR: Δ is in camera LDR units; the LDR model's is baked into its linearised colours
        delta = np.zeros(3, np.float32) if hdr else (self.history.total() - self.uploaded_total).astype(np.float32)
        with self.ctx.timed("cubemap"):
            faces = self.renderer.render(pos, p.face_size, delta, dense=p.dense, splat_m=p.splat_m,
                                         max_splat_px=p.max_splat_px, spheres=spheres)
        with self.ctx.timed("sh_projection"):
            coeffs = project_cubemap(faces if hdr else srgb_to_linear(np.clip(faces, 0, 1)), p.sh_bands)
        with self.ctx.timed("mips"):
            levels = prefilter(faces, p.mip_levels)
        header = Header(self.atlas.header.stamp_ns, "world")
        enc = self._encode_linear if hdr else self._encode
        mips = tuple(CubemapLevel(r, enc(f)) for r, f in levels[1:])
        observed = self._observed(pos, p.face_size)
        cube = Cubemap(header, oid, pos.copy(), enc(faces), mips, linear=hdr, observed=observed)
        sh = SHCoefficients(header, oid, p.sh_bands, coeffs.astype(np.float32))
        self.last_faces[oid] = linear_to_srgb(np.clip(faces, 0.0, 1.0)).astype(np.float32) if hdr else faces
        for envmap_out, sh_out in ((f"envmap/{oid}", f"sh/{oid}"), ("envmaps", "shs")):
            self.ctx.publish(envmap_out, cube)
            self.ctx.publish(sh_out, sh)
        self.counts["rendered_hdr" if hdr else "rendered"] += 1

    def _observed(self, pos: np.ndarray, size: int) -> np.ndarray:
        """Cubemap.observed of the map at ``pos`` (empty when the param is off)."""
        if not self.params.observed:
            return np.zeros((0, 0, 0), bool)
        with self.ctx.timed("observed"):
            return self.renderer.observed_mask(pos, size, dense=self.params.dense)

    def _encode(self, faces: np.ndarray) -> np.ndarray:
        f = np.clip(faces, 0.0, 1.0)
        return (f * 255.0 + 0.5).astype(np.uint8) if self.params.dtype == "uint8" else f.astype(np.float16)

    @staticmethod
    def _encode_linear(faces: np.ndarray) -> np.ndarray:
        return np.clip(faces, 0.0, FLOAT16_MAX).astype(np.float16)


    def close(self) -> None:
        if getattr(self, "last_faces", None) and self.params.net_dir:
            write_nets(self.last_faces, self.params.net_dir)
        if getattr(self, "renderer", None) is not None:
            self.renderer.release()
        if hasattr(self, "counts"):
            self.ctx.log.info("cubemap renderer: %s", dict(sorted(self.counts.items())))
