"""A frame source on its own thread: the node's thread only drains a queue and never blocks on a device."""

from __future__ import annotations

import queue
import threading
import time
from typing import Any, Callable, Iterator

END = object()  # queued after the last frame


class FrameThread(threading.Thread):
    """Runs a frame iterator on its own thread into a queue, so the node's thread never blocks on a device.

    ``wait`` (files): a full queue makes the reader wait and ``pace`` sleeps to the stamps' timing.
    Otherwise (live) a full queue drops its oldest frame (counted in ``dropped``). After the last
    frame (or an error, kept in ``error``) :data:`END` is queued and ``on_exit`` runs.
    """

    def __init__(self, frames: Iterator[tuple[int, Any]], name: str, *, wait: bool = False, pace: bool = False,
                 buffer: int = 2, on_exit: Callable[[], None] | None = None):
        super().__init__(name=name, daemon=True)
        self.frames, self.wait, self.pace, self.on_exit = frames, wait, pace, on_exit
        self.queue: queue.Queue = queue.Queue(maxsize=buffer)
        self.stopping = False
        self.error: BaseException | None = None
        self.dropped = 0
        self.pace_origin: float | None = None  # monotonic time frame 0 was due (pace only)

    def run(self) -> None:
        try:
            first = None
            for stamp, frame in self.frames:
                if self.stopping:
                    return
                if self.pace:
                    if first is None:
                        first, self.pace_origin = stamp, time.monotonic()
                    time.sleep(max(0.0, self.pace_origin + (stamp - first) / 1e9 - time.monotonic()))
                self._put((stamp, frame), self.wait)
        except BaseException as exc:  # re-raised on the node's thread by the consumer
            self.error = exc
        finally:
            if self.on_exit is not None:
                self.on_exit()
            self._put(END, True)

    def _put(self, item, wait: bool) -> None:
        while not self.stopping:
            try:
                self.queue.put(item, timeout=0.1 if wait else 0)
                return
            except queue.Full:
                if not wait:
                    try:
                        self.queue.get_nowait()
                        self.dropped += 1
                    except queue.Empty:
                        pass

    def stop(self) -> None:
        self.stopping = True


def drain(thread: FrameThread, publish: Callable[[int, Any], None]) -> bool:
    """``publish(stamp, frame)`` every queued frame; True once the stream ended (raises the thread's error)."""
    while True:
        try:
            item = thread.queue.get_nowait()
        except queue.Empty:
            return False
        if item is END:
            if thread.error is not None:
                raise thread.error
            return True
        publish(*item)
