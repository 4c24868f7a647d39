"""``probeless bench dense``: the dense model drawn into six cube faces by rasterising its points (our
cubemap renderer) vs Open3D's raycast of the same TSDF model, side by side in one run
(:func:`probeless.bench.dense_render.bench_dense_render`); goal ``dense_render_speedup`` >= 5 at 256^2,
point extraction and upload included, colour agreement gated."""

from __future__ import annotations

from probeless.bench.common import emit


def print_table(r: dict) -> None:
    print(f"dense model -> six {r['face_size']}^2 faces ({r['points']} points, {r['active_blocks']} TSDF blocks)")
    print(f"  ours (rasterised splats, coarse pass included): {r['ours_ms']:.1f} ms")
    print(f"  of which the coarse pass and read-back alone:   {r['ours_coarse_only_ms']:.1f} ms")
    print(f"  point extraction / upload (new model only):     {r['extract_ms']:.1f} / {r['upload_ms']:.1f} ms")
    print(f"  {r['dense_reference']}: {r['open3d_raycast_ms']:.1f} ms")
    print(f"  dense_render_speedup {r['dense_render_speedup']:.1f}x with extraction (goal >= 5), "
          f"{r['dense_render_speedup_same_model']:.1f}x same model, dense pass alone {r['dense_only_speedup']:.1f}x; "
          f"colour agreement where the raycast hits {100 * r['colour_agreement']:.0f} % (gate >= "
          f"{100 * r['colour_gate']['agreement_min']:.0f} %: {'met' if r['colour_gate_met'] else 'MISSED'})")


def main(json_out: bool = False, quick: bool = False) -> int:
    """Run the benchmark; a table, or exactly one JSON object with ``json_out``. 0 always (figures, not a test)."""
    from probeless.bench.dense_render import bench_dense_render
    from probeless.progress import stdout_to_stderr

    with stdout_to_stderr():  # Open3D logs on stdout
        r = bench_dense_render(repeats=2 if quick else 5)
    r["goal_speedup"] = 5.0
    r["meets_goal"] = bool(r["dense_render_speedup"] >= 5.0 and r["colour_gate_met"])
    emit(r, json_out, print_table)
    return 0


if __name__ == "__main__":
    from probeless.bench.common import module_main

    raise SystemExit(module_main(__spec__.name))
