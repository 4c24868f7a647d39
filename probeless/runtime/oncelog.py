"""Log a recurring problem once: nodes count every occurrence and say it the first time only."""

from __future__ import annotations

import logging


class OnceLog:
    """``log.<level>(text)`` the first time ``key`` is seen, nothing after (the node keeps the counts)."""

    def __init__(self, log: logging.Logger):
        self.log = log
        self.seen: set[str] = set()

    def _first(self, key: str) -> bool:
        if key in self.seen:
            return False
        self.seen.add(key)
        return True

    def warning(self, key: str, text: str) -> None:
        if self._first(key):
            self.log.warning("%s", text)

    def error(self, key: str, text: str) -> None:
        if self._first(key):
            self.log.error("%s", text)
