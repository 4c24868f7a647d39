"""``probeless bench pipeline``: a Table-1-like per-stage cost breakdown of the full pipeline.

Runs ``launch/probeless.yaml`` on the default scene (host-clock stamps) with a recorder on every
node's diagnostics and on ``compositor/image``; from the nodes' ``NodeStatus`` messages, the mean
time per stage (each node's own ``ctx.timed`` stages, count-weighted over its 1 s windows) and its
share of their sum; end-to-end latency from RGB capture to the augmented frame's publication
(p50/p99: the recorder's publish time minus the frame's stamp), the output frame rate, and the
frames each input dropped (queue policy) or lost upstream (seq gaps). The nodes run in parallel
processes on 2 shared cores, so stage times include waiting for the CPU.
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

from probeless.bench.common import emit
from probeless.paths import REPO_ROOT

GRAPH = REPO_ROOT / "launch" / "probeless.yaml"
# (label, node id, stage names) rows of the table, in pipeline order
STAGES = [
    ("SLAM (track + map)", "slam", ("on_input:rgb",)),
    ("fisheye undistortion", "undistort", ("remap",)),
    ("pose interpolation", "interp", ("interpolate",)),
    ("brightness estimation", "brightness", ("estimate",)),
    ("occlusion mask", "texturer", ("occlusion",)),
    ("coarse texture update", "texturer", ("texture_update",)),
    ("inpainting (amortised)", "texturer", ("inpaint",)),
    ("atlas read-back", "texturer", ("read_atlas",)),
    ("atlas upload (cubemap node)", "envmap", ("upload_atlas", "upload_dense")),
    ("cubemap render (coarse + dense)", "envmap", ("cubemap",)),
    ("SH projection + mips", "envmap", ("sh_projection", "mips")),
    ("IBL render", "compositor", ("upload", "render")),
    ("compositing", "compositor", ("composite",)),
]


def _stage_means(statuses) -> dict[str, dict[str, float]]:
    """node -> stage -> count-weighted mean ms over every diagnostics window."""
    acc: dict[str, dict[str, list[float]]] = defaultdict(lambda: defaultdict(lambda: [0.0, 0]))
    for st in statuses:
        for t in st.timings:
            a = acc[st.node_id][t.name]
            a[0] += t.mean_ms * t.count
            a[1] += t.count
    return {n: {s: (v[0] / v[1] if v[1] else float("nan")) for s, v in d.items()} for n, d in acc.items()}


def run_bench(quick: bool = False, seconds: float | None = None) -> dict:
    from probeless.bag.reader import BagReader
    from probeless.launch.launcher import Launcher, load_checked
    from probeless.launch.replay import add_recorder

    seconds = seconds or (2.0 if quick else 6.0)
    with tempfile.TemporaryDirectory() as tmp:
        graph = load_checked(str(GRAPH), {"seconds": seconds, "stamps": "wall", "out_dir": tmp})
        bag = str(Path(tmp) / "bench.mcap")
        topics = [f"{n}/diagnostics" for n in graph.nodes] + ["compositor/image"]
        add_recorder(graph, bag, topics=topics, diagnostics=True)
        t0 = time.monotonic()
        code = Launcher(graph, out=sys.stderr, ready_timeout=90.0).run()
        wall = time.monotonic() - t0
        if code != 0:
            raise RuntimeError(f"launch/probeless.yaml failed (exit code {code})")
        statuses, latencies, publish = [], [], []
        with BagReader(bag) as reader:
            for m in reader.messages():
                if m.topic.endswith("/diagnostics"):
                    statuses.append(reader.decode(m))
                elif m.topic == "compositor/image":
                    stamp = reader.decode(m).header.stamp_ns
                    latencies.append((m.publish_time_ns - stamp) / 1e6)
                    publish.append(m.publish_time_ns)
    means = _stage_means(statuses)
    from probeless.gl.context import create_context, device_name

    ctx = create_context()  # the device every GL node of the graph chose the same way (probeless.gl.context)
    gl_device = device_name(ctx)
    ctx.release()
    rows = []
    for label, node, names in STAGES:
        vals = [means.get(node, {}).get(s) for s in names]
        vals = [v for v in vals if v is not None and np.isfinite(v)]
        rows.append({"stage": label, "node": node, "ms": round(float(sum(vals)), 2) if vals else None})
    total = sum(r["ms"] for r in rows if r["ms"] is not None)
    for r in rows:
        r["percent"] = round(100 * r["ms"] / total, 1) if r["ms"] is not None and total else None
    last = {}
    for st in statuses:
        last[st.node_id] = st
    drops = {f"{n}/{i.name}": {"dropped": i.dropped, "seq_gaps": i.seq_gaps} for n, st in last.items()
             for i in st.inputs if i.dropped or i.seq_gaps}
    span = (publish[-1] - publish[0]) / 1e9 if len(publish) > 1 else float("nan")
    lat = np.array(latencies) if latencies else np.array([np.nan])
    return {"scene_seconds": seconds, "wall_s": round(wall, 1), "gl_device": gl_device, "stages": rows,
            "stage_sum_ms": round(total, 1),
            "augmented_frames": len(publish),
            "output_fps": round((len(publish) - 1) / span, 2) if len(publish) > 1 else None,
            "latency_rgb_to_augmented_ms": {"p50": round(float(np.nanpercentile(lat, 50)), 1),
                                            "p99": round(float(np.nanpercentile(lat, 99)), 1)},
            "dropped_per_input": drops}


def print_table(r: dict) -> None:
    print(f"full pipeline, {r['scene_seconds']} s of scene ({r['wall_s']} s wall), {os.cpu_count()} cores, "
          f"GL on {r['gl_device']}")
    print(f"{'stage':<34}{'node':<12}{'ms':>9}{'%':>7}")
    for row in r["stages"]:
        ms = "-" if row["ms"] is None else f"{row['ms']:.1f}"
        pc = "-" if row["percent"] is None else f"{row['percent']:.1f}"
        print(f"{row['stage']:<34}{row['node']:<12}{ms:>9}{pc:>7}")
    print(f"{'sum of stages':<46}{r['stage_sum_ms']:>9.1f}")
    lat = r["latency_rgb_to_augmented_ms"]
    print(f"augmented frames {r['augmented_frames']}, output {r['output_fps']} fps, "
          f"RGB capture -> augmented frame p50 {lat['p50']} ms, p99 {lat['p99']} ms")
    for k, v in r["dropped_per_input"].items():
        print(f"  {k}: dropped {v['dropped']}, seq gaps {v['seq_gaps']}")


def main(json_out: bool = False, quick: bool = False) -> int:
    """Run the benchmark; a table, or exactly one JSON object with ``json_out``. 0 always (figures, not a test)."""
    emit(run_bench(quick=quick), json_out, print_table)
    return 0


if __name__ == "__main__":
    from probeless.bench.common import module_main

    raise SystemExit(module_main(__spec__.name))
