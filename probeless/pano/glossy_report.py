"""Text table and JSON form of :func:`probeless.pano.glossy_eval.evaluate_glossy`'s result."""

from __future__ import annotations

from typing import Any


def _pct(err: dict[str, float]) -> str:
    return f"{100 * err['mean']:.2f}/{100 * err['max']:.1f}"


def _columns(settings: dict[str, Any]) -> list[tuple[str, str]]:
    """(result key, header) of every error column: ring (paper's lod rule), each lod bias, Monte Carlo and
    filtered importance sampling with the ring's lookup count, mirror, MC noise."""
    cols = [("ring", "ring")] + [(f"ring_lod_bias_{b:g}", f"bias {b:g}") for b in settings["lod_biases"] if b != 0.0]
    cols += [("mc_equal", "MC equal"), ("fis_equal", "FIS equal")]
    return cols + [("mirror", "mirror"), ("mc_noise", "MC noise")]


def format_table(res: dict[str, Any]) -> str:
    """Per panorama and roughness, then the summary over panoramas; errors as mean/max in percent."""
    s = res["settings"]
    cols = _columns(s)
    lines = [f"glossy ring sampling ({s['ring_samples']} samples) vs Monte Carlo ({s['mc_samples']} samples x 2 "
             f"seeds), {s['n_dirs']} random directions",
             f"error per direction = {s['metric']}; columns: mean/max over directions [%]; MC / FIS equal: "
             f"the same number of lookups as the ring; ratio = better equal-cost error / ring error", ""]
    head = f"{'panorama':26s} {'rough':>5s} {'n':>6s} {'lobe°':>6s}" + "".join(f" {h:>13s}" for _, h in cols)
    lines.append(head + f" {'ms/dir ring':>11s} {'ms/dir FIS':>10s} {'ratio':>6s}")
    for name, rows in res["panoramas"].items():
        for r, v in rows.items():
            lines.append(f"{name:26s} {r:>5s} {v['exponent']:6.0f} {v['lobe_half_angle_deg']:6.2f}"
                         + "".join(f" {_pct(v[k]):>13s}" for k, _ in cols)
                         + f" {v['ms_per_dir_ring']:11.3f} {v['ms_per_dir_fis_equal']:10.3f} "
                         f"{v['glossy_equal_cost_error_ratio']:6.2f}")
    lines += ["", "summary over panoramas (mean of the means / max of the maxima) [%]",
              f"{'rough':>5s}" + "".join(f" {h:>13s}" for _, h in cols) + f" {'ratio':>6s}"]
    for r, v in res["summary"].items():
        lines.append(f"{r:>5s}" + "".join(f" {_pct(v[k]):>13s}" for k, _ in cols)
                     + f" {v['glossy_equal_cost_error_ratio']:6.2f}")
    return "\n".join(lines)
