"""Running one sweep run in isolation (:func:`execute_run`) and many in a local pool (:func:`run_local`).

A run is ``python -m probeless ARGV`` in its own process group, with its own temporary directory
(``TMPDIR``) and IPC directory (``PROBELESS_RUN_DIR``), so parallel graphs never share a socket path or
a scratch file; its thread count is capped at the run's CPUs. :func:`execute_run` takes and returns plain
dicts, so the same function is a Ray task (:mod:`probeless.sweep.ray_runner`).
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from typing import Any, Callable, Iterator

STDERR_TAIL = 64 * 1024  # bytes of a run's stderr kept in its record (the log)
THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS")

_running: set[subprocess.Popen] = set()
_lock = threading.Lock()


def job_of(run, cwd: str, timeout_s: float | None, cpus: int) -> dict[str, Any]:
    """The plain-dict job of a :class:`~probeless.sweep.expand.Run` (picklable, for a pool or Ray)."""
    return {"run_id": run.run_id, "argv": list(run.argv), "cwd": cwd, "timeout_s": timeout_s, "cpus": cpus,
            "run_dir": run.run_dir, "result_file": run.result_file}


def run_env(tmp: str, cpus: int) -> dict[str, str]:
    """The environment of a run: private TMPDIR and IPC dir, threads capped at ``cpus``, no display."""
    ipc = os.path.join(tmp, "ipc")
    os.makedirs(ipc, mode=0o700)
    env = {**os.environ, "TMPDIR": tmp, "PROBELESS_RUN_DIR": ipc, "MPLBACKEND": "Agg"}
    env.update({k: str(max(1, cpus)) for k in THREAD_VARS})
    return env


def execute_run(job: dict[str, Any]) -> dict[str, Any]:
    """Run one job to the end; a record: status ok|failed, error, exit code, wall time, result JSON, logs."""
    t0 = time.monotonic()
    os.makedirs(job["run_dir"], exist_ok=True)  # graph runs write their outputs there
    tmp = tempfile.mkdtemp(prefix="pls-sweep-")  # short: IPC socket paths are limited to ~100 bytes
    timed_out = False
    try:
        proc = subprocess.Popen([sys.executable, "-m", "probeless", *job["argv"]], cwd=job["cwd"],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                env=run_env(tmp, job["cpus"]), start_new_session=True)
        with _lock:
            _running.add(proc)
        try:
            out, err = proc.communicate(timeout=job["timeout_s"])
        except subprocess.TimeoutExpired:
            timed_out = True
            kill(proc)
            out, err = proc.communicate()
        except BaseException:  # KeyboardInterrupt (a cancelled Ray task): the run's group goes with it
            kill(proc)
            raise
        finally:
            with _lock:
                _running.discard(proc)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    record = {"run_id": job["run_id"], "returncode": proc.returncode, "wall_s": round(time.monotonic() - t0, 3),
              "stdout": out, "stderr": err[-STDERR_TAIL:], "result": None, "status": "ok", "error": None}
    if timed_out:
        return {**record, "status": "failed", "error": f"timed out after {job['timeout_s']} s"}
    if proc.returncode != 0:
        return {**record, "status": "failed", "error": failure_message(err, proc.returncode)}
    try:
        record["result"] = read_result(out, job["result_file"])
    except (OSError, ValueError) as exc:
        return {**record, "status": "failed", "error": f"no JSON result: {exc}"}
    return record


def failure_message(stderr: str, returncode: int) -> str:
    """The run's own error line (``error: ...``), else its last line of stderr, with the exit status."""
    lines = [ln.strip() for ln in stderr.splitlines() if ln.strip()]
    errors = [ln for ln in lines if ln.startswith("error:") or "Error" in ln.split(":")[0]]
    last = (errors or lines or [""])[-1]
    return f"exit status {returncode}" + (f": {last}" if last else "")


def read_result(stdout: str, result_file: str | None) -> Any:
    """The run's JSON: the file a graph run writes, else the last line of an eval's stdout (``--json``)."""
    if result_file:
        with open(result_file) as f:
            return json.load(f)
    lines = [ln for ln in stdout.splitlines() if ln.strip()]
    if not lines:
        raise ValueError("the run printed nothing on stdout")
    return json.loads(lines[-1])


def kill(proc: subprocess.Popen) -> None:
    """End a run's whole process group: SIGTERM, then SIGKILL after 5 s."""
    for sig, grace in ((signal.SIGTERM, 5.0), (signal.SIGKILL, None)):
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            return
        if grace is None:
            return
        try:
            proc.wait(grace)
            return
        except subprocess.TimeoutExpired:
            pass


def kill_running() -> None:
    """End every run this process started that is still going (on Ctrl-C)."""
    with _lock:
        procs = list(_running)
    for proc in procs:
        kill(proc)


@contextlib.contextmanager
def interrupt_flag() -> Iterator[threading.Event]:
    """An event set by Ctrl-C meanwhile (in the main thread; elsewhere it is never set). The waiting loops poll
    it and raise KeyboardInterrupt themselves, never inside a lock of concurrent.futures or Ray."""
    stop = threading.Event()
    try:
        old = signal.signal(signal.SIGINT, lambda *_: stop.set())
    except ValueError:  # not the main thread
        yield stop
        return
    try:
        yield stop
    finally:
        signal.signal(signal.SIGINT, old)


def run_local(jobs: list[dict], slots: int, on_start: Callable[[dict], None],
              on_done: Callable[[dict], None]) -> None:
    """Run ``jobs`` with at most ``slots`` at once (each a process of its own); ``on_done(record)`` as each
    ends, in the calling thread. On Ctrl-C the running ones are killed and KeyboardInterrupt is raised."""

    def task(job):
        on_start(job)
        return execute_run(job)

    pool = ThreadPoolExecutor(max_workers=max(1, slots), thread_name_prefix="sweep")
    try:
        with interrupt_flag() as stop:
            pending = {pool.submit(task, job) for job in jobs}
            while pending:
                if stop.is_set():
                    raise KeyboardInterrupt
                done, pending = wait(pending, timeout=0.5, return_when=FIRST_COMPLETED)
                for future in done:
                    on_done(future.result())
    except BaseException:
        pool.shutdown(wait=False, cancel_futures=True)
        kill_running()
        raise
    pool.shutdown()
