"""CLI signal handling: SIGINT/SIGTERM end a tool cleanly; Ctrl-Z unsubscribes before stopping."""

from __future__ import annotations

import contextlib
import os
import signal
import threading
from typing import IO

from probeless.topics.reader import TopicReader

_suspend_requested = False


def _on_tstp(signum, frame) -> None:
    global _suspend_requested
    _suspend_requested = True


def _suspend_point(reader: TopicReader, err: IO[str]) -> bool:
    """After Ctrl-Z (CLI only): unsubscribe, stop the process, subscribe again on ``fg``/SIGCONT.

    A stopped process cannot drain its sockets, and publishers wait for a full subscriber (NODROP),
    so staying subscribed while stopped would hold up the graph. True when a suspension happened.
    """
    global _suspend_requested
    if not _suspend_requested:
        return False
    _suspend_requested = False
    reader.suspend()
    print("\n[suspended: unsubscribed so the graph is not held up; resubscribes on fg]", file=err, flush=True)
    os.kill(os.getpid(), signal.SIGSTOP)  # SIGSTOP: unlike SIGTSTP it also stops an orphaned process group
    reader.resume()
    print("[resumed: subscribed again; messages published meanwhile were not received]", file=err, flush=True)
    return True


@contextlib.contextmanager
def cli_signals(suspend: bool = False):
    """For the CLI: SIGINT and SIGTERM end a tool cleanly (sockets closed); with ``suspend``, Ctrl-Z
    unsubscribes before stopping (see :func:`_suspend_point`). A no-op outside the main thread."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    global _suspend_requested
    _suspend_requested = False
    wanted = {signal.SIGINT: interrupt, signal.SIGTERM: interrupt}
    if suspend:
        wanted[signal.SIGTSTP] = _on_tstp
    old = {}
    try:
        for sig, handler in wanted.items():
            old[sig] = signal.signal(sig, handler)
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)
