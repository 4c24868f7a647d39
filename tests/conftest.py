"""Suite-wide set-up: the tests' own helpers on sys.path, and how the suite runs under pytest-xdist.

`make test` runs the suite on two pytest-xdist workers (``-n 2 --dist loadfile``: a module's tests, and so its
module fixtures, stay on one worker). Two things keep that fast and fair:
- files that start node processes or are marked slow are handed out first, so no long file is left running alone
  at the end;
- tests whose assertions hold only with the machine to themselves (rates, stalls, memory growth measured in
  wall-clock time: ``EXCLUSIVE`` below, or ``@pytest.mark.exclusive``) take an exclusive lock that every other test
  holds shared, so they run while the other worker waits. Without xdist the lock is not taken.
"""

from __future__ import annotations

import fcntl
import os
import pathlib
import shutil
import sys
import tempfile

import pytest

sys.path.insert(0, str(pathlib.Path(__file__).parent))

# timing-sensitive files (relative to tests/): they run alone under xdist. Not here, as they hold under load:
# bench/test_bench_soak.py (descriptor, thread and total-RSS growth and flow, no rates; the docs' 30-minute soak
# ran beside the test suite), bag/test_recorder_memory.py (byte bounds; its "disk" is a sleep, slower than the
# camera under any load); topics/test_topic_tools.py marks its rate tests ``exclusive`` one by one.
EXCLUSIVE = (
    "faults/test_stalled_subscriber.py",
)
_TESTS = pathlib.Path(__file__).parent


_LOCKS = "PROBELESS_PYTEST_LOCKS"  # the lock files' folder, made by the xdist controller for its workers


def pytest_configure(config):
    if getattr(config, "workerinput", None) is None and config.getoption("numprocesses", None):
        config._probeless_locks = tempfile.mkdtemp(prefix="probeless-pytest-")
        os.environ[_LOCKS] = config._probeless_locks  # inherited by the workers it starts


def pytest_unconfigure(config):
    locks = getattr(config, "_probeless_locks", None)
    if locks:
        shutil.rmtree(locks, ignore_errors=True)
        os.environ.pop(_LOCKS, None)


def _weight(items) -> int:
    """A file's rough cost: slow tests count most, then tests that start node processes or need GL."""
    return sum(10 * ("slow" in i.keywords) + 2 * ("graph" in i.keywords) + ("gl" in i.keywords) for i in items)


def pytest_collection_modifyitems(config, items):
    rel = {}
    for item in items:
        path = pathlib.Path(str(item.fspath))
        rel[item.nodeid] = path.relative_to(_TESTS).as_posix() if path.is_relative_to(_TESTS) else path.name
        if rel[item.nodeid] in EXCLUSIVE:
            item.add_marker(pytest.mark.exclusive)
    if not os.environ.get("PYTEST_XDIST_WORKER"):
        return  # a plain run keeps pytest's order
    by_file: dict[str, list] = {}
    for item in items:
        by_file.setdefault(rel[item.nodeid], []).append(item)
    known = _durations()
    # longest first (known seconds from tests/durations.json, else the rough weight): the makespan of two workers
    # is shortest when no long file starts last
    order = sorted(by_file, key=lambda f: (-known.get(f, 0.0), -_weight(by_file[f])))  # stable: ties keep order
    items[:] = [i for f in order for i in by_file[f]]


def _durations() -> dict[str, float]:
    """{file relative to tests/: seconds} of a recent full run (``tools/test_durations.py`` writes it)."""
    import json

    path = _TESTS / "durations.json"
    try:
        return {str(k): float(v) for k, v in json.loads(path.read_text()).items()}
    except (OSError, ValueError, AttributeError):
        return {}


@pytest.hookimpl(hookwrapper=True, tryfirst=True)
def pytest_runtest_protocol(item, nextitem):
    """Under xdist: an ``exclusive`` test holds the run's lock exclusively, every other test holds it shared, from
    set-up (module fixtures included) to tear-down. A turnstile lock in front gives the exclusive test priority, so
    a busy worker cannot starve it. Outermost hook: the wait does not count against the test's timeout."""
    locks = os.environ.get(_LOCKS)
    if getattr(item.config, "workerinput", None) is None or not locks:
        yield
        return
    base = pathlib.Path(locks) / "run"
    exclusive = item.get_closest_marker("exclusive") is not None
    with open(f"{base}.turnstile", "a") as turn, open(f"{base}.lock", "a") as lock:
        fcntl.flock(turn, fcntl.LOCK_EX)
        if exclusive:
            fcntl.flock(lock, fcntl.LOCK_EX)
            fcntl.flock(turn, fcntl.LOCK_UN)
        else:
            fcntl.flock(turn, fcntl.LOCK_UN)
            fcntl.flock(lock, fcntl.LOCK_SH)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


@pytest.fixture
def short_run_dir():
    """A private runs folder (``PROBELESS_RUN_DIR``) short enough for ipc sockets: a unix socket path holds 107
    bytes, which pytest's own tmp_path under an xdist worker can nearly use up."""
    base = pathlib.Path(tempfile.mkdtemp(prefix="plr-", dir="/tmp"))
    yield base
    shutil.rmtree(base, ignore_errors=True)
