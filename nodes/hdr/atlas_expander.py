"""``hdr_atlas_expander``: the coarse model's camera-LDR atlas + an HDR photo -> an HDR atlas (paper 003's future
work with paper 001 §4).

Inputs ``atlas`` (``sensor/Image`` ``rgba8``: the texturer's published atlas, sRGB-encoded camera LDR, alpha > 0
where a texel was observed directly), ``floorplan`` (the room: the atlas layout is
:func:`probeless.coarse.model.make_layout` of it with ``atlas_size`` / ``texels_per_m`` exactly as in the texturer
and the cubemap renderer) and ``photo`` (``sensor/Image`` rgbf32/rgbf16, linear HDR, any units, e.g.
``panorama_source``'s ``hdr``). Output ``atlas`` (``sensor/Image`` ``rgbf32``, the same layout and size, the input
atlas's header): linear radiance >= 0 in the camera's linear units (1 = the fisheye's LDR white), unbounded above
- by the message convention a float image is linear. The cubemap renderer draws it with ``linear=True``.

The numeric work is :func:`probeless.hdr.coarse.expand_atlas` (observed core texels -> point cloud ->
:func:`probeless.hdr.expand.expand_cloud` -> back into the atlas; inpainted and unseen texels keep their linear
LDR value). An expansion takes seconds (a 1024² atlas with ~540k observed texels, pmatch-rgb, 2 views of 256 px:
11-17 s on 2 cores, the first in a process the slowest; 512²: 3.5 s), so the node keeps the latest atlas and
expands it when the photo and the floorplan are there, at most every ``min_period_s``: the first atlas at once, a
later one once the period is over (checked on each input and by a timer); the atlas held when the ``atlas`` input
ends is expanded then. A new photo alone does not re-expand. Bad inputs (an atlas of another encoding, a photo
that is not float, a floorplan the layout rejects, an atlas that does not fit the layout, an expansion that fails)
are counted in ``bad`` and logged, never raised; atlases with no observed texel yet are skipped and only counted.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import numpy as np

from probeless.coarse.model import CoarseConfig, make_layout
from probeless.coarse.texels import TexelMap, texel_map
from probeless.errors import ProbelessError
from probeless.hdr.coarse import expand_atlas
from probeless.hdr.expand import METHODS
from probeless.messages.geometry import Floorplan
from probeless.messages.sensor import Image
from probeless.nodes.hdr.expander import photo_array
from probeless.runtime import Node, param

ATLAS_ENCODING = "rgba8"


class HdrAtlasExpander(Node):
    """``atlas`` (rgba8) + ``floorplan`` + ``photo`` (rgbf32/rgbf16) -> ``atlas`` (rgbf32 linear radiance)."""

    INPUTS = {"atlas": Image, "floorplan": Floorplan, "photo": Image}
    OUTPUTS = {"atlas": Image}

    @dataclass(frozen=True)
    class Params:
        atlas_size: int = param(0, min=0, max=16384, doc="atlas side when texels_per_m is 0 [texels] (as the "
                                                         "texturer's); 0 = the width of the atlas images received")
        texels_per_m: float = param(0.0, min=0.0, max=10000.0,
                                    doc="texel density; 0 = fit atlas_size [texels/m] (as the texturer's)")
        method: str = param("pmatch-rgb", choices=METHODS, doc="expansion method (probeless.hdr.expand)")
        views: int = param(3, min=0, max=64, doc="view methods: views placed over the over-exposed clusters")
        transfer: str = param("rgb", choices=("rgb", "lum"), doc="transfer colour or luminance (and Poisson mode)")
        size: int = param(256, min=16, max=8192, doc="view width = height [px]")
        ssd_threshold: float = param(1.0, min=1e-9, max=1e9, doc="pmatch: patch SSD rejection threshold t_h")
        min_period_s: float = param(10.0, min=0.0, max=1e6, doc="at least this long between expansions [s]")

    def setup(self) -> None:
        self.photo: np.ndarray | None = None
        self.floorplan: Floorplan | None = None
        self.atlas: Image | None = None
        self.pending = False        # self.atlas is newer than the last expansion and not yet expanded
        self.texmap: TexelMap | None = None
        self.texmap_size = 0        # atlas side the texel map was made for
        self.last_time_ns: int | None = None
        self.expansions = 0
        self.empty_atlases = 0
        self.bad: Counter[str] = Counter()
        self.ctx.create_timer(0.25, self._on_timer, name="expand")

    def _bad(self, reason: str, text: str) -> None:
        self.bad[reason] += 1
        self.ctx.log.warning("hdr_atlas_expander: %s (%d bad input(s) so far)", text, sum(self.bad.values()))

    def on_input(self, name: str, msg) -> None:
        if name == "photo":
            photo, why = photo_array(msg)
            if photo is None:
                self._bad("photo_encoding", why)
                return
            self.photo = photo
        elif name == "floorplan":
            if self.floorplan is None or not np.array_equal(msg.vertices, self.floorplan.vertices) \
                    or msg.ceiling_height != self.floorplan.ceiling_height:
                self.floorplan, self.texmap = msg, None
        else:
            if msg.encoding != ATLAS_ENCODING:
                self._bad("atlas_encoding", f"atlas of encoding {msg.encoding!r} ignored, expected "
                                            f"{ATLAS_ENCODING} (the texturer's: alpha > 0 = observed)")
                return
            if not (msg.data[..., 3] > 0).any():  # nothing observed yet: nothing to expand, not an error
                self.empty_atlases += 1
                return
            self.atlas, self.pending = msg, True
        self._maybe_expand(final=False)

    def on_input_closed(self, name: str) -> None:
        if name == "atlas":
            self._maybe_expand(final=True)

    def _on_timer(self) -> None:
        self._maybe_expand(final=False)

    def _texel_map(self, width: int) -> TexelMap | None:
        """The texel map of the floorplan's layout (made once per floorplan and size); None when rejected."""
        p = self.params
        size = p.atlas_size or width
        if self.texmap is None or self.texmap_size != size:
            fp = self.floorplan
            try:
                layout = make_layout(fp.vertices, fp.ceiling_height, CoarseConfig(size, p.texels_per_m))
            except ProbelessError as exc:
                self._bad("floorplan", f"floorplan rejected: {exc}")
                return None
            self.texmap, self.texmap_size = texel_map(layout), size
        return self.texmap

    def _maybe_expand(self, final: bool) -> None:
        p = self.params
        if not self.pending or self.atlas is None or self.photo is None or self.floorplan is None:
            return
        now = self.ctx.now_ns()
        if (not final and self.last_time_ns is not None and p.min_period_s > 0
                and now - self.last_time_ns < p.min_period_s * 1e9):
            return
        atlas = self.atlas
        self.pending = False
        texmap = self._texel_map(atlas.data.shape[1])
        if texmap is None:
            return
        try:
            with self.ctx.timed("expand"):
                hdr = expand_atlas(atlas.data, texmap, self.photo, method=p.method, views=p.views,
                                   transfer=p.transfer, size=p.size, ssd_threshold=p.ssd_threshold)
        except ProbelessError as exc:
            self._bad("expansion", f"atlas {atlas.data.shape[1]}x{atlas.data.shape[0]} not expanded: {exc} "
                                   f"(give the texturer and this node the same atlas params)")
            return
        self.last_time_ns = now
        self.expansions += 1
        r = hdr.report
        self.ctx.log.info("expansion %d (%s): %d observed texels, %d in the cloud, alpha %s, %d over-exposed, "
                          "%d expanded, %d filled, max radiance %.3g", self.expansions, r["method"],
                          r["texels_observed"], r["texels_cloud"], "-" if r["alpha"] is None else f"{r['alpha']:.4g}",
                          r["points_overexposed"], r["points_expanded"], r["points_filled"], r["radiance_max"])
        self.ctx.publish("atlas", Image(atlas.header, np.ascontiguousarray(hdr.radiance, np.float32), "rgbf32"))

    def close(self) -> None:
        if getattr(self, "bad", None):
            self.ctx.log.warning("hdr_atlas_expander: bad inputs: %s", dict(self.bad))
