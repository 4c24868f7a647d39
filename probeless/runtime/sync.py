"""Time-synchronised multi-input helpers (like ROS message_filters), used inside ``on_input``.

::

    def setup(self):
        self.sync = ApproximateTimeSync(["rgb", "depth"], self.on_pair, slop_ns=5_000_000)

    def on_input(self, name, msg):
        self.sync.add(name, msg)

    def on_pair(self, msgs):            # {"rgb": Image, "depth": DepthImage}
        ...

Assumption: each input's ``header.stamp_ns`` arrive in non-decreasing order (true for one
publisher per topic). Emitted sets are in non-decreasing stamp order per input, so a message
older than its input's last emitted stamp can never be matched: it is reported unmatched with
reason ``"out_of_order"``. Every message ends up emitted once, reported unmatched once (through
``on_unmatched(name, msg, reason)`` and the counters), or still queued (:attr:`queued`).
Reasons: ``overflow``, ``no_match``, ``superseded``, ``out_of_order``, ``duplicate``, ``flushed``,
``time_jump``.

Clock jumps: a message older than its input's newest stamp by more than ``jump_back_ns`` (default
1 s) is a time jump (a host clock set back, a replay loop, a restarted source): every queued message
newer than it by more than ``jump_back_ns`` is reported unmatched (``time_jump``), the ordering state
of every input is forgotten, and matching starts afresh from it (counted in :attr:`time_jumps`).
Smaller disorder stays ``out_of_order``. A jump forwards needs nothing: older partners are dropped
as ``no_match`` until every input has jumped too, so nothing is ever emitted out of order.
"""

from __future__ import annotations

import bisect
import itertools
from collections import Counter
from typing import Callable, Sequence

from probeless.messages.base import Message

Callback = Callable[[dict[str, Message]], None]
Unmatched = Callable[[str, Message, str], None]
JUMP_BACK_NS = 1_000_000_000  # a stamp this much older than its input's newest is a time jump [ns]


class _Sync:
    """Shared bookkeeping: names, bounded queues, counters and the unmatched hook."""

    def __init__(self, names: Sequence[str], callback: Callback, queue_size: int,
                 on_unmatched: Unmatched | None, jump_back_ns: int = JUMP_BACK_NS):
        if not names or len(set(names)) != len(names):
            raise ValueError(f"need one or more distinct input names, got {list(names)!r}")
        if queue_size < 1:
            raise ValueError(f"queue_size must be >= 1, got {queue_size}")
        if jump_back_ns < 0:
            raise ValueError(f"jump_back_ns must be >= 0, got {jump_back_ns}")
        self.jump_back_ns = jump_back_ns
        self.time_jumps = 0                                 # backward time jumps seen [count]
        self._newest: dict[str, int | None] = dict.fromkeys(names)
        self.names = tuple(names)
        self.callback, self.queue_size, self.on_unmatched = callback, queue_size, on_unmatched
        self.matched = 0                                    # sets emitted [count]
        self.unmatched = 0                                  # messages reported unmatched [count]
        self.unmatched_by_reason: Counter[str] = Counter()  # reason -> messages [count]
        self._last_emitted: dict[str, int | None] = dict.fromkeys(self.names)
        self._queues: dict = {}

    @property
    def queued(self) -> int:
        """Messages held waiting for partners."""
        return sum(map(len, self._queues.values()))

    def _check(self, name: str) -> None:
        if name not in self._last_emitted:
            raise ValueError(f"unknown input {name!r} (synchronised: {', '.join(self.names)})")

    def _drop(self, name: str, msg: Message, reason: str) -> None:
        self.unmatched += 1
        self.unmatched_by_reason[reason] += 1
        if self.on_unmatched is not None:
            self.on_unmatched(name, msg, reason)

    def _emit(self, msgs: dict[str, Message]) -> None:
        for name, msg in msgs.items():
            self._last_emitted[name] = msg.header.stamp_ns
        self.matched += 1
        self.callback(msgs)

    def _stale(self, name: str, msg: Message) -> bool:
        """Report ``msg`` unmatched when it can never be emitted in order; handle a time jump first."""
        stamp, newest = msg.header.stamp_ns, self._newest[name]
        if newest is not None and newest - stamp > self.jump_back_ns:
            self._time_jump(stamp)
            newest = None
        self._newest[name] = stamp if newest is None else max(newest, stamp)
        last = self._last_emitted[name]
        if last is not None and msg.header.stamp_ns < last:
            self._drop(name, msg, "out_of_order")
            return True
        return False


    def _time_jump(self, stamp: int) -> None:
        """Forget the ordering before a backward jump to ``stamp``; drop what was queued from before it."""
        self.time_jumps += 1
        self._discard_queued(lambda s: s - stamp > self.jump_back_ns, "time_jump")
        self._reset_order()

    def _reset_order(self) -> None:
        self._last_emitted = dict.fromkeys(self.names)
        self._newest = dict.fromkeys(self.names)

    def _discard_queued(self, dead: Callable[[int], bool], reason: str) -> None:
        raise NotImplementedError


class ExactTimeSync(_Sync):
    """Emits ``{name: msg}`` once every input has a message with the same ``header.stamp_ns``."""

    def __init__(self, names: Sequence[str], callback: Callback, queue_size: int = 10,
                 on_unmatched: Unmatched | None = None, jump_back_ns: int = JUMP_BACK_NS):
        super().__init__(names, callback, queue_size, on_unmatched, jump_back_ns)
        self._queues: dict[str, dict[int, Message]] = {n: {} for n in self.names}
        self._last_seen: dict[str, int | None] = dict.fromkeys(self.names)

    def _reset_order(self) -> None:
        super()._reset_order()
        self._last_seen = {n: max(q) if q else None for n, q in self._queues.items()}

    def _discard_queued(self, dead: Callable[[int], bool], reason: str) -> None:
        self._discard(lambda n, s: dead(s), reason)

    def add(self, name: str, msg: Message) -> None:
        """Queue a message of input ``name``; may call the callback and ``on_unmatched``."""
        self._check(name)
        if self._stale(name, msg):
            return
        stamp, queue = msg.header.stamp_ns, self._queues[name]
        if stamp in queue:
            self._drop(name, queue.pop(stamp), "duplicate")
        queue[stamp] = msg
        last = self._last_seen[name]
        self._last_seen[name] = stamp if last is None else max(last, stamp)
        if all(stamp in q for q in self._queues.values()):
            msgs = {n: q.pop(stamp) for n, q in self._queues.items()}
            self._discard(lambda n, s: s < stamp, "superseded")
            self._emit(msgs)
        # (i, s) is dead once another input, arriving in order, has gone past s without it.
        self._discard(lambda n, s: any(j != n and s not in q and self._last_seen[j] is not None
                                       and self._last_seen[j] > s for j, q in self._queues.items()), "no_match")
        while len(queue) > self.queue_size:
            self._drop(name, queue.pop(min(queue)), "overflow")

    def flush(self) -> None:
        """Report every queued message unmatched (reason ``flushed``), e.g. at end of stream."""
        self._discard(lambda n, s: True, "flushed")

    def _discard(self, dead: Callable[[str, int], bool], reason: str) -> None:
        for name, queue in self._queues.items():
            for stamp in [s for s in queue if dead(name, s)]:
                self._drop(name, queue.pop(stamp), reason)


class ApproximateTimeSync(_Sync):
    """Emits one message per input whose stamps all lie within ``slop_ns`` of each other.

    While every queue is non-empty: pivot = newest head stamp. A head older than
    ``pivot - slop_ns`` can never match (the pivot input only goes forward): reported
    ``no_match``. Otherwise each input's candidate is its queued message closest to the pivot
    (ties: the older) and the candidates are emitted, or the heads if the candidates span more
    than ``slop_ns``. Messages older than an emitted one are reported ``superseded``. Queues are
    bounded by ``queue_size`` (oldest dropped, ``overflow``) after matching has been tried.

    By default (``wait_for_nearest=True``) a set is emitted only once every input holds a message
    at or after the pivot, so no later arrival can be nearer; this costs up to one message period
    of latency. ``wait_for_nearest=False`` emits eagerly: lower latency, but with ``slop_ns``
    above half an input's period the partner chosen can depend on arrival order.
    :meth:`flush` matches eagerly.
    """

    def __init__(self, names: Sequence[str], callback: Callback, slop_ns: int, queue_size: int = 10,
                 on_unmatched: Unmatched | None = None, wait_for_nearest: bool = True,
                 jump_back_ns: int = JUMP_BACK_NS):
        super().__init__(names, callback, queue_size, on_unmatched, jump_back_ns)
        if slop_ns < 0:
            raise ValueError(f"slop_ns must be >= 0, got {slop_ns}")
        self.slop_ns, self.wait_for_nearest = slop_ns, wait_for_nearest
        self._queues: dict[str, list[tuple[int, int, Message]]] = {n: [] for n in self.names}
        self._seq = itertools.count()

    def _discard_queued(self, dead: Callable[[int], bool], reason: str) -> None:
        for name, queue in self._queues.items():
            for entry in [e for e in queue if dead(e[0])]:
                queue.remove(entry)
                self._drop(name, entry[2], reason)

    def add(self, name: str, msg: Message) -> None:
        """Queue a message of input ``name``; may call the callback and ``on_unmatched``."""
        self._check(name)
        if self._stale(name, msg):
            return
        bisect.insort(self._queues[name], (msg.header.stamp_ns, next(self._seq), msg))
        self._match()
        queue = self._queues[name]
        while len(queue) > self.queue_size:
            self._drop(name, queue.pop(0)[2], "overflow")
            self._match()

    def flush(self) -> None:
        """Emit what still matches without waiting, then report the rest unmatched (``flushed``)."""
        self._match(wait=False)
        for name, queue in self._queues.items():
            while queue:
                self._drop(name, queue.pop(0)[2], "flushed")

    def _match(self, wait: bool | None = None) -> None:
        wait = self.wait_for_nearest if wait is None else wait
        queues, slop = self._queues, self.slop_ns
        while all(queues.values()):
            heads = {n: q[0][0] for n, q in queues.items()}
            pivot = max(heads.values())
            oldest = min(heads, key=heads.__getitem__)
            if heads[oldest] < pivot - slop:
                self._drop(oldest, queues[oldest].pop(0)[2], "no_match")
                continue
            if wait and any(q[-1][0] < pivot for q in queues.values()):
                return  # wait: a later arrival could be closer to the pivot
            picks = {n: min((k for k, e in enumerate(q) if abs(e[0] - pivot) <= slop),
                            key=lambda k, q=q: abs(q[k][0] - pivot)) for n, q in queues.items()}
            stamps = [queues[n][k][0] for n, k in picks.items()]
            if max(stamps) - min(stamps) > slop:
                picks = dict.fromkeys(queues, 0)
            msgs = {}
            for n, k in picks.items():
                for entry in queues[n][:k]:
                    self._drop(n, entry[2], "superseded")
                msgs[n] = queues[n][k][2]
                del queues[n][:k + 1]
            self._emit(msgs)
