"""Benchmarks: ``probeless bench NAME [--json] [--quick] [its own options]``, or ``python -m probeless.bench.NAME``.

``BENCHMARKS`` maps each benchmark's name to its module and a one-line help. Every benchmark module
exposes ``main(json_out, quick)``, and where it has options of its own ``add_arguments(parser)``
(``--json`` and ``--quick`` come from :func:`probeless.bench.common.add_common_arguments`) and
``run(ns) -> int``. Benchmarks launch
graphs of registered node types (the benchmark nodes are in ``probeless.nodes.bench``); they never
import ``probeless.nodes``. Importing this package is cheap: modules are imported when run.
"""

from __future__ import annotations

BENCHMARKS: dict[str, tuple[str, str]] = {
    "bus": ("probeless.bench.bus", "our node-to-node bus vs raw pyzmq PUB/SUB: throughput, latency, loss"),
    "bag": ("probeless.bench.bag", "recording: recorder vs raw mcap writer, replay timing, lockstep determinism"),
    "sensors": ("probeless.bench.sensors", "synthetic rig render rate, undistortion cost and vs cv2.omnidir"),
    "undistort": ("probeless.bench.undistort",
                  "fisheye undistortion: table build and remap cost, vs cv2.omnidir.initUndistortRectifyMap"),
    "slam": ("probeless.bench.slam", "dense SLAM: step costs, sustained node rate, node overhead"),
    "coarse": ("probeless.bench.coarse", "coarse room model: occlusion, texture update, brightness (vectorised "
                                         "vs a compiled serial loop; sampled vs all texels), inpainting, read-back"),
    "pipeline": ("probeless.bench.pipeline", "full pipeline: per-stage costs, latency, frame rate, drops"),
    "dense": ("probeless.bench.dense", "dense model cubemap rendering (point extraction included) vs Open3D raycast"),
    "pano": ("probeless.bench.pano", "360° video IBL: ITMO, diffuse map vs exact FFT convolution, glossy at equal "
                                     "cost, compositing"),
    "hdr": ("probeless.bench.hdr", "HDR expansion of a 0.8M-point cloud end to end (paper 001, Table 1)"),
    "pbgi": ("probeless.bench.pbgi",
             "PBGI: BSH build, Classic / Mipmapped / Hybrid time and memory (paper 001, Table 3)"),
    "soak": ("probeless.bench.soak", "full pipeline on a looping recording for --minutes N: RSS, open descriptors "
                                     "and threads per process over time, growth after warm-up"),
}

__all__ = ["BENCHMARKS"]
