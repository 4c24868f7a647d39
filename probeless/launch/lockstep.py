"""Quiescence for lockstep replay: is every node idle with nothing in flight?

The player asks the launcher after each message. The launcher collects a status snapshot from
every other running node (busy flag, queued messages, received per input, published per topic)
and declares the graph quiet when (a) no node is busy or has anything queued, (b) on every wired
edge the subscriber has received exactly what the publisher published, and (c) two consecutive
collects are identical. Counters only grow, so (c) means no event happened between the collects
(the classic double collect): the state seen is a real, consistent, quiet state.
"""

from __future__ import annotations

from typing import Any


class QuiescenceCheck:
    """One pending quiescence request of ``requester`` (the player)."""

    def __init__(self, plan: dict[str, Any], requester: str, requester_published: dict[str, int]):
        self.plan = plan
        self.requester = requester
        self.requester_published = requester_published
        self.round = 0
        self.expected: set[str] = set()
        self.replies: dict[str, dict] = {}
        self.previous: dict[str, dict] | None = None
        self.busy_rounds = 0  # consecutive collects that found work in progress

    def retry_delay_s(self) -> float:
        """How long to wait before the next collect: none right after a quiet one (the confirming collect),
        then 0.25 ms doubling to 8 ms while nodes work, so that asking does not take the CPU from the work."""
        if self.previous is not None:
            return 0.0
        self.busy_rounds += 1
        return 0.00025 * 2 ** min(self.busy_rounds - 1, 5)  # 8 ms from the sixth round on (a long stage)

    def begin_round(self, alive: list[str]) -> list[str]:
        """Start a collect; returns the node ids to ask for status."""
        self.round += 1
        self.expected = {n for n in alive if n != self.requester}
        self.replies = {}
        return sorted(self.expected)

    def add_reply(self, node_id: str, round_id: int, snapshot: dict) -> bool:
        """Record a status reply; True when the current collect is complete."""
        if round_id == self.round and node_id in self.expected:
            self.replies[node_id] = snapshot
        return set(self.replies) == self.expected

    def quiet(self) -> bool:
        """Evaluate a complete collect: True when quiet and identical to the previous collect."""
        current = self.replies
        ok = all(not s["busy"] and s["queued"] == 0 for s in current.values()) and self._edges_balanced(current)
        stable = ok and self.previous == current
        self.previous = current if ok else None
        return stable

    def _edges_balanced(self, snaps: dict[str, dict]) -> bool:
        published: dict[str, int] = dict(self.requester_published)
        for s in snaps.values():
            published.update(s["published"])
        for node_id, snap in snaps.items():
            spec = self.plan["nodes"][node_id]
            wired = [(i["name"], i["topic"], i["source_node"]) for i in spec["inputs"] if "topic" in i]
            if spec.get("clock"):
                wired.append(("__clock__", spec["clock"]["topic"], spec["clock"]["source_node"]))
            for name, topic, source in wired:
                if source != self.requester and source not in snaps:
                    continue  # publisher ended (it drained before exiting) or is not ours
                if snap["received"].get(name, 0) != published.get(topic, 0):
                    return False
        return True
