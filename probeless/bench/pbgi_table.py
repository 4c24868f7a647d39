"""Table 3 of ``probeless bench pbgi``: timing the variants per configuration, the equality gate, the time
budget, the Hybrid threshold sweep (see :mod:`probeless.bench.pbgi`)."""

from __future__ import annotations

import math
import statistics
import time

from probeless.bench.common import log
from probeless.bench.pbgi_scenes import (
    FIGURE_CONFIG,
    LONG_ROUND_S,
    PAPER,
    SCENES,
    SWEEP_CONFIG,
    SWEEP_FACTORS,
    VARIANTS,
    Renderers,
    Scene,
    Settings,
    camera,
    image_difference,
    render_once,
)


def time_jobs(jobs: dict, cam, size: int, repeat: int, long_s: float = LONG_ROUND_S) -> tuple[dict, dict, int]:
    """Time ``jobs`` {label: (renderer, variant)} in rounds that interleave them. Returns ({label: figures of its
    best run, with ``runs_ms``}, {label: first image}, rounds run). A round over ``long_s`` s is not repeated; a
    failed job is not retried."""
    best: dict = {}
    images: dict = {}
    runs: dict = {k: [] for k in jobs}
    rounds = 0
    for _ in range(repeat):
        t0 = time.perf_counter()
        for k, (renderer, variant) in jobs.items():
            if "error" in best.get(k, {}):
                continue
            fig, out = render_once(renderer, cam, size, variant)
            if out is None:
                best.setdefault(k, fig)
                continue
            images.setdefault(k, out)
            runs[k].append(fig["ms"])
            if k not in best or fig["ms"] < best[k]["ms"]:
                best[k] = fig
        rounds += 1
        if time.perf_counter() - t0 > long_s:
            break
    for k, fig in best.items():
        if "ms" in fig:
            fig["runs_ms"] = runs[k]
    return best, images, rounds


def compare_variants(figs: dict, images: dict) -> dict:
    """Same-work figures and speedups of one configuration (in place into ``figs``' variants)."""
    out = {"object_pixels": None, "equal": True}
    ref = images.get("classic")
    if ref is not None:
        out["object_pixels"] = int(ref.mask.sum())
    for v in ("mipmapped", "hybrid"):
        if v not in figs:
            continue
        if ref is not None and v in images:
            figs[v].update(image_difference(ref, images[v], ref.mask))
            out["equal"] &= figs[v]["equal"]
        for key, suffix in (("ms", ""), ("cpu_ms", "_cpu")):
            c, t = figs.get("classic", {}).get(key), figs[v].get(key)
            out[f"{v}_speedup{suffix}"] = c / t if c and t else None
    return out


def null_config(variants, reason: str) -> dict:
    """A configuration that did not run: every variant null with ``reason``."""
    return {"variants": {v: {"ms": None, "error": reason} for v in variants}, "skipped": reason, "equal": True}


# -- Table 3 ---------------------------------------------------------------------------------------------------------

def plan(st: Settings, scenes: dict) -> list[tuple[str, int, int, int]]:
    """(scene, view, viewport, micro) from the least work up (View2 before View1 at equal work)."""
    todo = [(s, v, n, m) for s in st.scenes if isinstance(scenes.get(s), Scene)
            for v in st.views for n in st.viewports for m in st.micros]
    return sorted(todo, key=lambda c: (c[2] ** 2 * c[3] ** 2, -c[1], SCENES.index(c[0])))


class Budget:
    """Predicts a configuration's seconds from the rate (seconds per pixel x micro-texel) of the largest
    configuration run so far of the same scene and view, and says whether it still fits."""

    def __init__(self, seconds: float, start: float):
        self.seconds, self.start = float(seconds), start
        self.rates: dict[tuple, tuple[float, float, int]] = {}  # (scene, view) -> (work, s/work per round, rounds)

    def predict(self, key, work: float, repeat: int) -> float | None:
        if key not in self.rates:
            return None
        _, rate, _ = self.rates[key]
        one = rate * work
        return one * (1 if one > LONG_ROUND_S else repeat)

    def fits(self, key, work: float, repeat: int) -> tuple[bool, str]:
        left = self.seconds - (time.perf_counter() - self.start)
        pred = self.predict(key, work, repeat)
        if pred is not None and pred > left:
            return False, f"skipped: time budget (predicted {pred:.0f} s, {max(left, 0):.0f} s of --budget left)"
        return True, ""

    def record(self, key, work: float, seconds: float, rounds: int) -> None:
        if key not in self.rates or work >= self.rates[key][0]:
            self.rates[key] = (work, seconds / max(rounds, 1) / work, rounds)


def run_config(renderers: Renderers, scene: Scene, view: int, size: int, micro: int, repeat: int) -> tuple:
    """(row, hybrid image or None, rounds) of one configuration."""
    from probeless.errors import PbgiError

    try:
        r = renderers.get(scene, micro)
    except PbgiError as exc:
        return null_config(VARIANTS, f"error: {exc}"), None, 0
    figs, images, rounds = time_jobs({v: (r, v) for v in VARIANTS}, camera(scene, view, size), size, repeat)
    row = {"variants": figs, **compare_variants(figs, images), "rounds": rounds}
    return row, images.get("hybrid"), rounds


def table3(st: Settings, scenes: dict, renderers: Renderers, budget: Budget) -> tuple[list, dict]:
    """Every configuration of :func:`plan` (rows in plan order) and the Hybrid images at :data:`FIGURE_CONFIG`."""
    from probeless.progress import progress

    rows, figure_images = [], {}
    todo = plan(st, scenes)
    with progress(len(todo), "pbgi Table 3", transient=True) as tick:
        for name, view, size, micro in todo:
            key, work = (name, view), float(size * size * micro * micro)
            ok, reason = budget.fits(key, work, st.repeat)
            head = {"scene": name, "view": view, "viewport": size, "micro": micro}
            if not ok:
                log(f"{name} View{view} {size}^2 micro {micro}^2: {reason}")
                rows.append({**head, **null_config(VARIANTS, reason)})
                tick()
                continue
            t0 = time.perf_counter()
            row, hybrid, rounds = run_config(renderers, scenes[name], view, size, micro, st.repeat)
            seconds = time.perf_counter() - t0
            if rounds:
                budget.record(key, work, seconds, rounds)
            if hybrid is not None and (size, micro) == FIGURE_CONFIG:
                figure_images[key] = hybrid
            rows.append({**head, **row, "seconds": seconds})
            log(f"{name} View{view} {size}^2 micro {micro}^2: " + ", ".join(
                f"{v} {row['variants'][v]['ms']:.0f} ms" if row["variants"][v].get("ms") else f"{v} x"
                for v in VARIANTS) + f" ({seconds:.0f} s)")
            tick()
    return rows, figure_images


def speedup_summary(rows: list) -> dict:
    """Per variant: the max and median over the configurations of its speedup over Classic (PBGI wall time), and
    the same of the process CPU time (``cpu``: less sensitive to other processes on the shared cores)."""
    out = {}
    for v in ("hybrid", "mipmapped"):
        out[v] = {}
        for suffix, into in (("", out[v]), ("_cpu", out[v].setdefault("cpu", {}))):
            vals = [r[f"{v}_speedup{suffix}"] for r in rows if r.get(f"{v}_speedup{suffix}")]
            into.update({"max": max(vals) if vals else None,
                         "median": statistics.median(vals) if vals else None, "configs": len(vals)})
    return out


# -- hybrid threshold sweep ------------------------------------------------------------------------------------------

def sweep(st: Settings, scenes: dict, renderers: Renderers) -> dict | None:
    """Hybrid time per omega_tr factor at :data:`SWEEP_CONFIG` (the first scene there when room is not run)."""
    name, view, size, micro = SWEEP_CONFIG
    if name not in scenes or not isinstance(scenes[name], Scene):
        name = next((s for s in st.scenes if isinstance(scenes.get(s), Scene)), None)
        if name is None:
            return None
    scene, cam = scenes[name], camera(scenes[name], view, size)
    jobs = {"classic": (renderers.get(scene, micro), "classic")}
    jobs.update({f: (renderers.get(scene, micro, f), "hybrid") for f in SWEEP_FACTORS})
    figs, images, _ = time_jobs(jobs, cam, size, st.repeat, long_s=math.inf)
    ref = images.get("classic")
    points = []
    for f in SWEEP_FACTORS:
        row = {"factor": f, **figs[f]}
        if ref is not None and f in images:
            row.update(image_difference(ref, images[f], ref.mask))
        points.append(row)
        log(f"sweep omega_tr = {f:g} omega: " + (f"{row['ms']:.0f} ms" if row.get("ms") else "x"))
    timed = [p for p in points if p.get("ms")]
    fastest = min(timed, key=lambda p: p["ms"])["factor"] if timed else None
    return {"scene": name, "view": view, "viewport": size, "micro": micro, "classic_ms": figs["classic"].get("ms"),
            "points": points, "fastest_factor": fastest, "paper_factor": PAPER["hybrid_factor"],
            "equal": all(p.get("equal", False) for p in timed)}


# -- figure ----------------------------------------------------------------------------------------------------------
