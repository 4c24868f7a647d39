"""Micro-buffer PBGI on the GPU (paper 001 §5.2–5.4): Classic, Mipmapped and Hybrid traversals, and shading.

All three fill the same micro-buffers (``micro`` x ``micro`` texels per receiver pixel, see
``shaders/pbgi_common.glsl``) from a cut of the BSH and then run the same shading pass (Eq. 9), so their images
differ only where their cuts do:

* ``classic`` -- one compute invocation per pixel walks the whole tree depth-first (``pbgi_classic.comp.glsl``);
* ``mipmapped`` -- iterations over (node, G-buffer pixel) pairs starting at (root, coarsest pixel); each pair
  refines the node or the pixel (Figure 7) or splats (``pbgi_pairs.comp.glsl``);
* ``hybrid`` -- the mipmapped iterations refine nodes only while they subtend at least ``omega_tr`` (32 micro-texel
  solid angles, §5.2.2); the pairs that reach level 0 are finished by the classic walk of their sub-tree;
* ``envmap`` -- no traversal: every texel reads the far-field cubemap (the environment-map baseline with the same
  shading).

The paper's geometry shader + transform feedback become compute shaders appending pairs to storage buffers with
an atomic counter: the same data flow, but llvmpipe runs compute shaders on every core while it runs the geometry
stage with transform feedback on one, and append buffers need no primitive-count queries. Receivers are processed
in batches of whole G-buffer tiles so the micro-buffers fit ``budget`` bytes (llvmpipe caps a storage buffer at
128 MiB). The extra memory of Table 3 is the peak size of the pair buffers in use (``MicroStats.pair_bytes``).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import moderngl
import numpy as np

from probeless.errors import PbgiError
from probeless.gl.programs import load_program, set_uniforms
from probeless.pbgi.bsh import NODE_DTYPE

SHADERS = Path(__file__).with_name("shaders")
VARIANTS = ("classic", "mipmapped", "hybrid", "envmap")
MAT_DTYPE = np.dtype([("base", "<f4", (3,)), ("roughness", "<f4"), ("metalness", "<f4"), ("model", "<u4"),
                      ("pad", "<f4", (2,))])
MAX_BUFFER = 128 << 20  # llvmpipe's GL_MAX_SHADER_STORAGE_BLOCK_SIZE [bytes]
_GROUP = 64
DEPTH_MIN = 0.01  # nearest depth the texel keys resolve [m]; nearer points share the first step
VOR_BITS = 3  # nearness-rank bits of a texel key (pbgi_common.glsl)
# A splat's depth in a texel key is pushed back by RIM_DEPTH * t [log m] at its nearness rank t (0 at the node's
# centre, 1 at its rim; pbgi_common.glsl texel_key): a node's bounding disk covers more than its points, so where a
# nearer node only reaches with its rim, a node behind it within ~RIM_DEPTH * d that is hit near its centre keeps the
# texel. Without it a decal 0.5-5 mm in front of its wall covered the wall beyond its edges (quantised depth always
# won) and lit a sphere up to 8 % brighter than the same decal coplanar; with 0.1 it is within 1 % (tests/pbgi/
# test_decals.py, `probeless eval pbgi --rooms decals,decals_0.5mm,decals_1mm,decals_5mm`; docs/pbgi).
RIM_DEPTH = 0.1
WORK_CAP = 8192  # work units per classic invocation and dispatch (pbgi_classic.comp.glsl)


@dataclass
class MicroStats:
    """What one render did: sizes, work and time."""

    variant: str
    micro: int             # micro-buffer side [texels]
    pixels: int            # receivers (level-0 pixels)
    batches: int
    iterations: int = 0    # pair iterations (mipmapped / hybrid)
    pairs: int = 0         # pairs processed by the pair iterations
    classic_pairs: int = 0  # (node, pixel) walks run by the classic program
    classic_dispatches: int = 0  # dispatches of the classic program (walks resume across them)
    pair_bytes: int = 0    # peak bytes of pair buffers in use (the paper's extra memory)
    micro_bytes: int = 0   # micro-buffer storage [bytes]
    seconds: float = 0.0   # traversal + shading, GPU finished
    shade_seconds: float = 0.0  # of which shading (Eq. 9)


def disk_texels(micro: int) -> int:
    """Micro-buffer texels whose centres lie inside the unit disk (the hemisphere's projection)."""
    q = (np.arange(micro) + 0.5) / micro * 2 - 1
    return int(((q[:, None] ** 2 + q[None, :] ** 2) < 1).sum())


def _groups(n: int) -> tuple[int, int]:
    g = max(1, math.ceil(n / _GROUP))
    return (g, 1) if g <= 65535 else (65535, math.ceil(g / 65535))


class MicroBufferRenderer:
    """Micro-buffer traversal and shading on one GL context (see the module docstring).

    ``micro``: micro-buffer side (16, 24, 32 in the paper); ``hybrid_factor``: omega_tr in micro-texel solid angles;
    ``is_roughness``/``is_samples``: the importance-sampled specular lookup below that roughness (0 disables);
    ``budget``: bytes of micro-buffers per batch.
    """

    def __init__(self, ctx: moderngl.Context, *, micro: int = 24, hybrid_factor: float = 32.0,
                 is_roughness: float = 0.2, is_samples: int = 64, budget: int = 64 << 20, supersample: int = 1):
        if not 4 <= int(micro) <= 64:
            raise PbgiError(f"micro-buffer side must be in [4, 64], got {micro}")
        side = int(micro) * int(supersample)
        if budget > MAX_BUFFER or budget < side * side * 4:
            raise PbgiError(f"micro-buffer budget must be in [{side * side * 4}, {MAX_BUFFER}] bytes, got {budget}")
        if not 1 <= int(supersample) <= 4:
            raise PbgiError(f"supersample must be 1..4, got {supersample}")
        self.ctx, self.micro, self.budget = ctx, int(micro), int(budget)
        self.side = self.micro * int(supersample)  # texels per micro-buffer row
        self.hybrid_factor, self.is_roughness, self.is_samples = float(hybrid_factor), float(is_roughness), int(
            is_samples)
        self.progs = {k: load_program(ctx, f"pbgi_{k}", shader_dir=SHADERS) for k in ("classic", "pairs", "shade")}
        self.nodes_buf = None
        self.n_nodes = 0
        self._bufs: dict[str, moderngl.Buffer] = {}

    @property
    def omega(self) -> float:
        """Solid angle of a micro-texel as Eq. 5 takes it: 2 pi / M^2 [sr]."""
        return 2.0 * math.pi / self.micro ** 2

    @property
    def tile_levels(self) -> int:
        """Mip levels above the pixels: the largest whose tiles' micro-buffers fit one batch."""
        per = self.side * self.side * 4
        return max(0, int(math.floor(math.log2(self.budget // per) / 2)))

    def set_nodes(self, nodes: np.ndarray) -> None:
        """Upload a linearised BSH (:data:`~probeless.pbgi.bsh.NODE_DTYPE`, depth-first)."""
        nodes = np.asarray(nodes)
        if nodes.dtype != NODE_DTYPE or nodes.ndim != 1 or nodes.size == 0:
            raise PbgiError(f"set_nodes: expected a non-empty 1-D NODE_DTYPE array, got {nodes.dtype} {nodes.shape}")
        if nodes.nbytes > MAX_BUFFER or nodes.size >= 1 << 21:
            raise PbgiError(f"set_nodes: {nodes.size} nodes exceed the limit of {(1 << 21) - 1} (texel keys hold "
                            f"a 21-bit slot, 8 depth and {VOR_BITS} rank bits; prune or use a larger voxel)")
        if self.nodes_buf is not None:
            self.nodes_buf.release()
        self.nodes_buf = self.ctx.buffer(nodes.tobytes())
        self.n_nodes = int(nodes.size)
        self.bounds = (nodes["center"].min(0) - nodes["radius"].max(), nodes["center"].max(0) + nodes["radius"].max())

    def _buffer(self, name: str, nbytes: int, exact: bool = False) -> moderngl.Buffer:
        buf = self._bufs.get(name)
        if buf is None or buf.size < nbytes or (exact and buf.size != nbytes):
            if buf is not None:
                buf.release()
            buf = self._bufs[name] = self.ctx.buffer(reserve=max(int(nbytes), 16))
        return buf

    def _batches(self, pyr) -> list[tuple[int, int, int, int]]:
        """[(top start, top end, level-0 start, level-0 end)] of whole top-level tiles within the budget."""
        cap = self.budget // (self.side * self.side * 4)
        lo, top = pyr.offsets[-2], pyr.offsets[-1]
        out, a, s0, acc = [], lo, 0, 0
        for t in range(lo, top):
            b = int(pyr.below[t - lo])
            if b > cap:
                raise PbgiError(f"a G-buffer tile has {b} pixels, more than a batch of {cap} micro-buffers holds")
            if acc + b > cap:
                out.append((a, t, s0, s0 + acc))
                a, s0, acc = t, s0 + acc, 0
            acc += b
        out.append((a, top, s0, s0 + acc))
        return out

    def render(self, pyr, materials: np.ndarray, camera_position, variant: str = "hybrid", *,
               far_field: moderngl.TextureCube | None = None,
               near: tuple | None = None) -> tuple[np.ndarray, MicroStats]:
        """Radiance (N0, 3) float32 leaving each level-0 pixel of pyramid ``pyr`` towards ``camera_position``.

        ``materials``: :data:`MAT_DTYPE` per level-0 pixel; ``far_field``: cubemap read by empty texels;
        ``near``: (centre, radius): only nodes within radius of centre are gathered (near-field mode).
        """
        if variant not in VARIANTS:
            raise PbgiError(f"unknown PBGI variant {variant!r} (known: {', '.join(VARIANTS)})")
        if variant != "envmap" and self.nodes_buf is None:
            raise PbgiError("render: no point cloud hierarchy uploaded yet (set_nodes)")
        if variant == "envmap" and far_field is None:
            raise PbgiError("render: the envmap variant needs a far-field cubemap")
        t0 = time.perf_counter()
        n0 = pyr.n_pixels
        batches = self._batches(pyr)
        stats = MicroStats(variant, self.micro, n0, len(batches))
        self._bind_common(pyr, materials, camera_position, far_field, near)
        for top0, top1, s0, s1 in batches:
            self._buffer("micro", (s1 - s0) * self.side ** 2 * 4).clear(chunk=b"\xff\xff\xff\xff")
            self._set_all(slot_base=s0)
            if variant == "classic":
                self._classic(None, s1 - s0, s0, stats)
            elif variant in ("mipmapped", "hybrid"):
                self._pairs(np.arange(top0, top1, dtype=np.uint32), variant == "hybrid", stats)
            self.ctx.finish()
            ts = time.perf_counter()
            self._shade(s0, s1)
            self.ctx.finish()
            stats.shade_seconds += time.perf_counter() - ts
        stats.micro_bytes = self._bufs["micro"].size
        out = np.frombuffer(self._bufs["radiance"].read(n0 * 16), np.float32).reshape(n0, 4)[:, :3].copy()
        stats.seconds = time.perf_counter() - t0
        return out, stats

    def _set_all(self, **values) -> None:
        for p in self.progs.values():
            set_uniforms(p, **values)

    def _bind_common(self, pyr, materials, camera_position, far_field, near) -> None:
        n0 = pyr.n_pixels
        if materials.dtype != MAT_DTYPE or materials.shape != (n0,):
            raise PbgiError(f"render: materials must be ({n0},) MAT_DTYPE, got {materials.dtype} {materials.shape}")
        if self.nodes_buf is None:
            self.set_nodes(np.zeros(1, NODE_DTYPE))
        self._buffer("gpix", pyr.records.nbytes, exact=True).write(pyr.records.tobytes())
        self._buffer("mats", materials.nbytes, exact=True).write(materials.tobytes())
        self._buffer("radiance", n0 * 16)
        lo, hi = self.bounds
        pts = pyr.records["position"]
        extent = np.linalg.norm(np.maximum(hi, pts.max(0)) - np.minimum(lo, pts.min(0)))
        idx_bits = self.idx_bits = max(1, math.ceil(math.log2(self.n_nodes + 1)))
        if 32 - idx_bits - VOR_BITS < 8:
            raise PbgiError(f"{self.n_nodes} nodes leave {32 - idx_bits - VOR_BITS} depth bits in a texel key "
                            f"(at least 8 needed; prune the cloud or use a larger voxel)")
        self._set_all(M=self.side, omega_stop=4.0 * self.omega, idx_bits=idx_bits, log_dmin=math.log(DEPTH_MIN),
                      log_drange=math.log(max(2.0 * extent, 1e-3)) - math.log(DEPTH_MIN), rim_depth=RIM_DEPTH,
                      near_center=tuple(float(v) for v in (near[0] if near else (0, 0, 0))),
                      near_radius=float(near[1]) if near else -1.0)
        ang = np.arange(256) * math.pi / 255
        for prog in self.progs.values():
            if "cone_cs" in prog:
                prog["cone_cs"].write(np.stack([np.cos(ang), np.sin(ang)], 1).astype("f4").tobytes())
        self.nodes_buf.bind_to_storage_buffer(0)
        self._bufs["gpix"].bind_to_storage_buffer(1)
        self._buffer("micro", 16).bind_to_storage_buffer(2)
        if far_field is not None:
            far_field.use(0)
        set_uniforms(self.progs["shade"], far_field=0, has_far=far_field is not None,
                     camera_position=tuple(float(v) for v in camera_position), is_roughness=self.is_roughness,
                     is_samples=self.is_samples, texel_area=math.pi / disk_texels(self.side))

    def _run(self, prog, n: int, **uniforms) -> None:
        self._bufs["micro"].bind_to_storage_buffer(2)
        set_uniforms(prog, **uniforms)
        prog.run(*_groups(n))
        self.ctx.memory_barrier()

    def _classic(self, pairs_buf, n: int, first: int, stats: MicroStats) -> None:
        """Classic walks for ``n`` pairs (``pairs_buf``, or (root, pixel first + k)), dispatched until all are done
        (see ``pbgi_classic.comp.glsl`` for why a walk is resumable)."""
        prog = self.progs["classic"]
        (pairs_buf or self._buffer("pairs_dummy", 16)).bind_to_storage_buffer(3)
        walks = self._buffer("walks", n * 4)
        walks.clear(size=n * 4, chunk=b"\xff\xff\xff\xff")
        walks.bind_to_storage_buffer(7)
        counters = self._buffer("counters", 16, exact=True)
        counters.bind_to_storage_buffer(6)
        set_uniforms(prog, n_pairs=n, implicit_root=pairs_buf is None, pixel_first=first, work_cap=WORK_CAP)
        while True:
            counters.write(np.zeros(4, np.uint32).tobytes())
            self._run(prog, n)
            stats.classic_dispatches += 1
            if not int(np.frombuffer(counters.read(4), np.uint32)[0]):
                break
        stats.classic_pairs += n

    def _pairs(self, top: np.ndarray, hybrid: bool, stats: MicroStats) -> None:
        """Run pair iterations from (root, each top-level pixel) until no pair is left. A wave is a list of pair
        buffers; an input range whose output would overflow a buffer is split in halves and rerun (its splats are
        idempotent atomicMins)."""
        prog, counters = self.progs["pairs"], self._buffer("counters", 16, exact=True)
        start = np.stack([np.zeros_like(top), top], 1).astype(np.uint32)
        wave = [(self.ctx.buffer(start.tobytes()), len(start))]
        cap_max = MAX_BUFFER // 8
        omega_tr = self.hybrid_factor * self.omega
        while wave:
            nxt = []
            live = sum(n for _, n in wave)
            todo = [(buf, 0, n) for buf, n in wave]
            while todo:
                buf, off, n = todo.pop()
                cap = min(cap_max, 4 * n)
                out = self.ctx.buffer(reserve=cap * 8)
                cls = self._buffer("pairs_classic", max(n, 1) * 8) if hybrid else self._buffer("pairs_classic", 16)
                counters.write(np.zeros(4, np.uint32).tobytes())
                buf.bind_to_storage_buffer(3)
                out.bind_to_storage_buffer(4)
                cls.bind_to_storage_buffer(5)
                counters.bind_to_storage_buffer(6)
                self._run(prog, n, n_pairs=off + n, pair_offset=off, cap_out=cap, cap_classic=max(n, 1),
                          hybrid=hybrid, omega_tr=omega_tr)
                n_out, n_cls = (int(v) for v in np.frombuffer(counters.read(8), np.uint32))
                if n_out > cap:
                    out.release()
                    if n == 1:
                        raise PbgiError(f"pair buffer overflow: one pair made {n_out} pairs")
                    todo += [(buf, off, n // 2), (buf, off + n // 2, n - n // 2)]
                    continue
                stats.iterations += 1
                stats.pairs += n
                live += n_out + n_cls
                stats.pair_bytes = max(stats.pair_bytes, 8 * live)
                if n_cls:
                    self._classic(cls, n_cls, 0, stats)
                live -= n_cls
                if n_out:
                    nxt.append((out, n_out))
                else:
                    out.release()
            for buf, n in wave:
                buf.release()
                live -= n
            wave = nxt

    def _shade(self, s0: int, s1: int) -> None:
        self._bufs["mats"].bind_to_storage_buffer(3)
        self._bufs["radiance"].bind_to_storage_buffer(4)
        self._run(self.progs["shade"], s1 - s0, n_pixels=s1 - s0, pixel_first=s0)

    def last_micro_buffers(self) -> np.ndarray:
        """(pixels, M, M) uint32 micro-buffers of the last batch rendered (texel codes, see pbgi_common.glsl)."""
        m = self.side
        return np.frombuffer(self._bufs["micro"].read(), np.uint32).reshape(-1, m, m).copy()

    def release(self) -> None:
        for b in self._bufs.values():
            b.release()
        self._bufs = {}
        if self.nodes_buf is not None:
            self.nodes_buf.release()
            self.nodes_buf = None
