"""Running sweep jobs as Ray tasks (``probeless sweep --ray auto|ADDRESS``; the extra ``probeless[cluster]``).

Each job is one task of :func:`probeless.sweep.runner.execute_run` with the run's CPUs and GPUs as its
resources, so Ray's scheduler packs them; the task still runs the command as its own isolated process.
``auto`` starts a local Ray for the sweep (and stops it after); an address connects to a running cluster,
whose nodes must see the repository and the results directory at the same paths (a shared filesystem).
A Ray already initialised by the caller (a test, a notebook) is used as it is and left running.
"""

from __future__ import annotations

import time
from typing import Any, Callable

from probeless.errors import SweepError
from probeless.sweep.runner import execute_run, interrupt_flag

CANCEL_WAIT_S = 10.0  # for cancelled tasks to kill their runs (kill: SIGTERM, SIGKILL after 5 s)
INSTALL = "pip install 'probeless[cluster]'"


def import_ray():
    """The ``ray`` module, or a SweepError saying how to install it."""
    try:
        import ray
    except ImportError:
        raise SweepError(f"--ray needs Ray, which is not installed: {INSTALL}") from None
    return ray


def init_ray(address: str, cpus: int | None = None) -> tuple[Any, bool, float]:
    """(ray, whether we started it, seconds it took). ``auto``: a local Ray of ``cpus`` CPUs."""
    ray = import_ray()
    if ray.is_initialized():
        return ray, False, 0.0
    t0 = time.monotonic()
    if address == "auto":
        ray.init(num_cpus=cpus, include_dashboard=False, log_to_driver=False, configure_logging=False)
    else:
        ray.init(address=address, log_to_driver=False, configure_logging=False)
    return ray, True, time.monotonic() - t0


def run_ray(jobs: list[dict], address: str, cpus_per_run: int, gpus_per_run: float, local_cpus: int,
            on_start: Callable[[dict], None], on_done: Callable[[dict], None]) -> float:
    """Run ``jobs`` as Ray tasks; ``on_done(record)`` as each ends. Returns Ray's start-up time [s] (0 when
    Ray was already running). On Ctrl-C the tasks are cancelled; each kills its run's processes."""
    ray, started, startup_s = init_ray(address, local_cpus)
    try:
        task = ray.remote(num_cpus=cpus_per_run, num_gpus=gpus_per_run, max_retries=0)(execute_run)
        pending = {}
        for job in jobs:
            pending[task.remote(job)] = job
            on_start(job)
        try:
            with interrupt_flag() as stop:
                while pending:
                    if stop.is_set():
                        raise KeyboardInterrupt
                    done, _ = ray.wait(list(pending), num_returns=1, timeout=0.5)
                    for ref in done:
                        pending.pop(ref)
                        on_done(ray.get(ref))
        except BaseException:
            for ref in pending:
                ray.cancel(ref)  # KeyboardInterrupt in the task: it kills its run
            ray.wait(list(pending), num_returns=len(pending), timeout=CANCEL_WAIT_S)  # before ray.shutdown
            raise
    finally:
        if started:
            ray.shutdown()
    return startup_s
