"""``probeless bag record`` without ``--graph``: record topics of a graph that is already running."""

from __future__ import annotations

import copy
import shutil
import signal
import sys
import threading
from typing import Any

from probeless.errors import BagError
from probeless.launch.plan import new_run_dir
from probeless.launch.replay import RECORDER_ID
from probeless.runtime.process import NodeRuntime
from probeless.runtime.queues import RECORDER_QUEUE_BYTES, input_queue_bytes
from probeless.topics import graph_topics, select_graph


def record_running_graph(path: str, topics: list[str] | None, params: dict[str, Any], *,
                         graph_dir: str | None = None, duration: float | None = None,
                         queue_bytes: int = RECORDER_QUEUE_BYTES) -> int:
    """Record ``topics`` (default: all) of the running graph until it ends, SIGINT/SIGTERM or ``duration``.

    The recorder joins late, so it records from now on (no readiness barrier), losslessly:
    its inputs use ``policy: block``, their queues together bounded by ``queue_bytes``.
    """
    graph = select_graph(graph_dir)
    available = graph_topics(graph)
    chosen = list(topics) if topics else sorted(available)
    unknown = [t for t in chosen if t not in available]
    if unknown:
        raise BagError(f"cannot record {unknown}: not a topic of the running graph {graph.plan.get('file')} "
                       f"(topics: {sorted(available)})")
    run_dir = new_run_dir()
    plan = copy.deepcopy(graph.plan)
    plan["control"] = None
    plan["nodes"][RECORDER_ID] = {
        "id": RECORDER_ID, "index": len(plan["nodes"]), "node": "bag_recorder", "params": {"path": path, **params},
        "endpoint": f"ipc://{run_dir}/recorder.pub", "outputs": {},
        "inputs": [{"name": t, "topic": t, "endpoint": available[t].endpoint, "type_name": None,
                    "source_node": available[t].publisher, "output": t.rsplit("/", 1)[-1],
                    "policy": "block", "queue_size": 256, "max_bytes": input_queue_bytes(len(chosen), queue_bytes)}
                   for t in chosen]}
    runtime = NodeRuntime(plan, RECORDER_ID, "inproc://wake-recorder")

    def stop(*_: Any) -> None:
        runtime.stop_requested = True

    old = {s: signal.signal(s, stop) for s in (signal.SIGINT, signal.SIGTERM)}
    done = threading.Event()
    if duration:  # counted from the moment the recorder is subscribed, not from the start of its set-up
        threading.Thread(target=_stop_after, args=(runtime, duration, done, stop), daemon=True).start()
    print(f"recording {len(chosen)} topic(s) of {graph.describe()} to {path}; Ctrl-C to stop", file=sys.stderr)
    try:
        return runtime.run()
    finally:
        done.set()
        for s, h in old.items():
            signal.signal(s, h)
        shutil.rmtree(run_dir, ignore_errors=True)


def _stop_after(runtime: NodeRuntime, duration: float, done: threading.Event, stop: Any) -> None:
    """Stop the recorder ``duration`` seconds after it started recording."""
    while runtime.state != "running" and not done.wait(0.02):
        pass
    if not done.wait(duration):
        stop()
