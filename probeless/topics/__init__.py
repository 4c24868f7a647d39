"""``probeless topic list | echo | hz | info | pub``: the topics of a running graph (``node``, ``param``
and ``runs`` are in :mod:`probeless.topics.nodes`, ``pub`` in :mod:`probeless.topics.pub`).

A running graph is found through its run directory (``$PROBELESS_RUN_DIR`` or
``$TMPDIR/probeless-<uid>``, one sub-directory per launch) holding the launcher's ``graph.json``
plan, whose ``launcher_pid`` must still be alive.

The tools subscribe through the runtime's own :class:`~probeless.runtime.transport.Receiver`: its
thread drains the SUB socket continuously and applies a dropping queue policy, and it connects to
the publisher's lossy socket, so a tool that is slow (a slow terminal) or stopped never pushes back
on the graph: the publisher drops for that tool alone. Tool-side drops are counted and
reported separately from messages lost upstream (``header.seq`` gaps). On end of stream the
receiver closes the socket at once (publishers wait for that before they exit), and every socket
is opened with linger 0.

Python API (``out``/``err`` are text streams; every function raises ProbelessError on a user error)::

    g = select_graph()                            # the only running graph, or select_graph(RUN_ID | GRAPH_FILE)
    graph_topics(g)                               # {topic: Topic}
    list_topics(g, verbose=False, out=sys.stdout)
    echo(g, "src/image", count=3, arrays=True)    # -> number of messages printed
    hz(g, "src/image", window=100, duration=3.0)  # -> final statistics (dict)
    topic_info(g, "src/image", timeout=2.5)       # -> dict; print_info(info) prints it
    topic_main(["echo", "src/image", "-n", "3"])  # the CLI without probeless.cli, -> exit code
"""

from probeless.topics.catalog import Subscriber, Topic, find_topic, graph_topics, list_topics
from probeless.topics.cli import (
                                  add_topic_parser,
                                  cmd_topic_echo,
                                  cmd_topic_hz,
                                  cmd_topic_info,
                                  cmd_topic_list,
                                  topic_main,
)
from probeless.topics.discovery import (
                                  NO_GRAPH_HINT,
                                  RunningGraph,
                                  load_graph_dir,
                                  pid_alive,
                                  running_graphs,
                                  runs_base,
                                  select_graph,
)
from probeless.topics.echo import echo
from probeless.topics.formatting import MAX_INLINE_ITEMS, format_message, summarize_array
from probeless.topics.hz import RateStats, format_rate, hz
from probeless.topics.info import print_info, topic_info
from probeless.topics.reader import SURELY_STARTED_S, TopicReader, wait_for_start
from probeless.topics.signals import cli_signals

__all__ = [
    "MAX_INLINE_ITEMS", "NO_GRAPH_HINT", "SURELY_STARTED_S", "RateStats", "RunningGraph", "Subscriber", "Topic",
    "TopicReader", "add_topic_parser", "cli_signals", "cmd_topic_echo", "cmd_topic_hz", "cmd_topic_info",
    "cmd_topic_list", "echo", "find_topic", "format_message", "format_rate", "graph_topics", "hz", "list_topics",
    "load_graph_dir", "pid_alive", "print_info", "running_graphs", "runs_base", "select_graph", "summarize_array",
    "topic_info", "topic_main", "wait_for_start",
]
