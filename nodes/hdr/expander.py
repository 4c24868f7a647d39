"""``hdr_expander``: an LDR coloured point cloud + an HDR photo -> an HDR point cloud (paper 001, §4).

Inputs ``cloud`` (``mesh/PointCloud``: the SLAM node's ``model/points`` or ``cloud_file``; uint8
colours are sRGB codes, float colours linear 0..1) and ``photo`` (``sensor/Image`` rgbf32/rgbf16,
linear HDR, any units, e.g. ``panorama_source``'s ``hdr``). Output ``cloud`` (``mesh/HdrPointCloud``,
the input cloud's header). The numeric work is :func:`probeless.hdr.expand.expand_cloud`; the node
keeps the latest photo and the latest cloud and expands when both are there and the cloud is new
enough: the first cloud, then only one that has grown by ``min_growth`` (a fraction of the point
count at the last expansion) and not sooner than ``min_period_s`` after it. A cloud held back by
``min_period_s`` alone is expanded when the ``cloud`` input ends. A new photo alone does not
re-expand; it is used from the next expansion. Bad inputs (an empty cloud, a photo of another
encoding, a cloud the expansion rejects) are counted in ``bad`` and logged, never raised; empty clouds
(a live model before its first fusion) are skipped and only counted.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import numpy as np

from probeless.errors import HdrError
from probeless.hdr.expand import METHODS, expand_cloud
from probeless.hdr.views import linear_colors
from probeless.messages.mesh import HdrPointCloud, PointCloud
from probeless.messages.sensor import Image
from probeless.runtime import Node, param

PHOTO_ENCODINGS = ("rgbf32", "rgbf16")


def photo_array(msg: Image) -> tuple[np.ndarray | None, str]:
    """(linear HDR photo as float32 (H, W, 3), "") or (None, why it is refused): the ``photo`` input of the
    HDR nodes."""
    if msg.encoding not in PHOTO_ENCODINGS:
        return None, f"photo of encoding {msg.encoding!r} ignored, expected {' or '.join(PHOTO_ENCODINGS)}"
    return np.asarray(msg.data, np.float32), ""


class HdrExpander(Node):
    """``cloud`` (PointCloud) + ``photo`` (rgbf32/rgbf16) -> ``cloud`` (HdrPointCloud), see the module docstring."""

    INPUTS = {"cloud": PointCloud, "photo": Image}
    OUTPUTS = {"cloud": HdrPointCloud}

    @dataclass(frozen=True)
    class Params:
        method: str = param("pmatch-rgb", choices=METHODS, doc="expansion method (probeless.hdr.expand)")
        views: int = param(3, min=0, max=64, doc="view methods: views placed over the over-exposed clusters")
        transfer: str = param("rgb", choices=("rgb", "lum"), doc="transfer colour or luminance (and Poisson mode)")
        size: int = param(1024, min=16, max=8192, doc="view width = height [px]")
        ssd_threshold: float = param(1.0, min=1e-9, max=1e9, doc="pmatch: patch SSD rejection threshold t_h")
        robust: bool = param(True, doc="pmatch: drop values disagreeing with their clipped cluster (not in the paper)")
        min_growth: float = param(0.05, min=0.0, max=1e6,
                                  doc="re-expand only when the cloud grew by this fraction since the last expansion")
        min_period_s: float = param(0.0, min=0.0, max=1e6, doc="at least this long between expansions [s]")

    def setup(self) -> None:
        self.photo: np.ndarray | None = None
        self.cloud: PointCloud | None = None
        self.pending = False        # self.cloud is newer than the last expansion and not yet expanded
        self.last_points = 0        # point count at the last expansion (0 = none yet)
        self.last_time_ns: int | None = None
        self.expansions = 0
        self.bad: Counter[str] = Counter()
        self.empty_clouds = 0

    def _bad(self, reason: str, text: str) -> None:
        self.bad[reason] += 1
        self.ctx.log.warning("hdr_expander: %s (%d bad input(s) so far)", text, sum(self.bad.values()))

    def on_input(self, name: str, msg) -> None:
        if name == "photo":
            photo, why = photo_array(msg)
            if photo is None:
                self._bad("photo_encoding", why)
                return
            self.photo = photo
        else:
            if len(msg) == 0:  # a SLAM model before its first fusion: nothing to expand yet, not an error
                self.empty_clouds += 1
                return
            grown = self.last_points == 0 or len(msg) >= self.last_points * (1.0 + self.params.min_growth)
            if not grown:
                return
            self.cloud, self.pending = msg, True
        self._maybe_expand(final=False)

    def on_input_closed(self, name: str) -> None:
        if name == "cloud":
            self._maybe_expand(final=True)

    def _maybe_expand(self, final: bool) -> None:
        p = self.params
        if not self.pending or self.cloud is None or self.photo is None:
            return
        now = self.ctx.now_ns()
        if (not final and self.last_time_ns is not None and p.min_period_s > 0
                and now - self.last_time_ns < p.min_period_s * 1e9):
            return
        cloud = self.cloud
        self.pending = False
        normals = cloud.normals if len(cloud.normals) else None
        try:
            with self.ctx.timed("expand"):
                result = expand_cloud(cloud.points, cloud.colors, self.photo, method=p.method, views=p.views,
                                      transfer=p.transfer, normals=normals, size=p.size,
                                      ssd_threshold=p.ssd_threshold, robust=p.robust)
        except HdrError as e:
            self._bad("expansion", f"cloud of {len(cloud)} points not expanded: {e}")
            return
        self.last_points, self.last_time_ns = len(cloud), now
        self.expansions += 1
        r = result.report
        self.ctx.log.info("expansion %d (%s): %d points, alpha %s, %d over-exposed, %d expanded, %d filled, "
                          "%d left LDR, max radiance %.3g", self.expansions, r["method"], r["points"],
                          "-" if r["alpha"] is None else f"{r['alpha']:.4g}", r["points_overexposed"],
                          r["points_expanded"], r["points_filled"], r["points_left_ldr"], r["radiance_max"])
        for w in r.get("warnings", []):
            self.ctx.log.warning("hdr_expander: expansion %d: %s", self.expansions, w)
        ldr = np.clip(linear_colors(cloud.colors), 0.0, 1.0).astype(np.float32)
        self.ctx.publish("cloud", HdrPointCloud(cloud.header, cloud.points,
                                                np.ascontiguousarray(result.radiance, np.float32),
                                                cloud.normals, ldr))

    def close(self) -> None:
        if getattr(self, "bad", None):
            self.ctx.log.warning("hdr_expander: bad inputs: %s", dict(self.bad))
