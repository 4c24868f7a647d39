"""``probeless sweep bench SWEEP.yaml``: wall time of the same sweep on the local pool at each ``--jobs``
value, and on a local Ray (``--ray auto``): Ray's start-up, and its per-task overhead two ways: the
round trip of an empty task, and (Ray sweep - start-up - pool sweep at the same jobs) / runs.
Each sweep is run from scratch in a temporary results directory."""

from __future__ import annotations

import tempfile
import time
from typing import Any

from probeless.sweep.driver import run_sweep

EMPTY_TASKS = 50


def _empty() -> int:
    return 0


def empty_task_s(address: str, cpus: int) -> tuple[float, float]:
    """(Ray start-up [s], mean round trip of an empty task [s], sequential, after one warm-up)."""
    from probeless.sweep.ray_runner import init_ray

    ray, started, startup_s = init_ray(address, cpus)
    try:
        task = ray.remote(num_cpus=1)(_empty)
        ray.get(task.remote())
        t0 = time.monotonic()
        for _ in range(EMPTY_TASKS):
            ray.get(task.remote())
        return startup_s, (time.monotonic() - t0) / EMPTY_TASKS
    finally:
        if started:
            ray.shutdown()


def bench(sweep_file: str, jobs_list: list[int], ray: str | None = None, only: list[str] = ()) -> dict[str, Any]:
    """The timings (module doc) as a dict."""
    out: dict[str, Any] = {"sweep": sweep_file, "pool": {}}
    runs = 0
    for jobs in jobs_list:
        with tempfile.TemporaryDirectory(prefix="sweep-bench-") as d:
            s = run_sweep(sweep_file, d, jobs=jobs, only=only, show_progress=False)
        runs = s.total
        out["pool"][jobs] = {"wall_s": round(s.wall_s, 2), "failed": s.failed}
    out["runs"] = runs
    if ray:
        jobs = max(jobs_list)
        with tempfile.TemporaryDirectory(prefix="sweep-bench-") as d:
            s = run_sweep(sweep_file, d, jobs=jobs, ray=ray, only=only, show_progress=False)
        startup_s, empty_s = empty_task_s(ray, jobs)
        pool = out["pool"][jobs]["wall_s"]
        out["ray"] = {"jobs": jobs, "startup_s": round(s.ray_startup_s or 0.0, 2),
                      "sweep_wall_s": round(s.wall_s, 2), "sweep_minus_startup_s": round(s.wall_s - (
                          s.ray_startup_s or 0.0), 2), "failed": s.failed,
                      "per_task_overhead_s": round((s.wall_s - (s.ray_startup_s or 0.0) - pool) / max(1, runs), 3),
                      "second_startup_s": round(startup_s, 2), "empty_task_round_trip_ms": round(empty_s * 1e3, 2)}
    return out


def format_bench(res: dict[str, Any]) -> str:
    """The timings as text."""
    lines = [f"sweep {res['sweep']}: {res['runs']} runs"]
    for jobs, r in res["pool"].items():
        lines.append(f"  local pool --jobs {jobs}: {r['wall_s']:.2f} s ({r['failed']} failed)")
    if "ray" in res:
        r = res["ray"]
        lines += [f"  Ray (local, {r['jobs']} CPUs): sweep {r['sweep_wall_s']:.2f} s, of which start-up "
                  f"{r['startup_s']:.2f} s ({r['failed']} failed)",
                  f"  Ray per-task overhead vs the pool: {r['per_task_overhead_s']:.3f} s/run; empty-task round "
                  f"trip {r['empty_task_round_trip_ms']:.2f} ms; a second Ray start-up {r['second_startup_s']:.2f} s"]
    return "\n".join(lines)
