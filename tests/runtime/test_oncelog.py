"""OnceLog: the first occurrence of each key is logged at its level, later ones are not."""

from __future__ import annotations

import logging

from probeless.runtime.oncelog import OnceLog


def test_each_key_is_logged_once_at_its_level(caplog):
    once = OnceLog(logging.getLogger("oncelog-test"))
    with caplog.at_level(logging.WARNING, logger="oncelog-test"):
        for _ in range(3):
            once.warning("a", "first a 100%")
            once.error("b", "first b")
        once.warning("c", "c")
    assert [(r.levelno, r.getMessage()) for r in caplog.records] == [
        (logging.WARNING, "first a 100%"), (logging.ERROR, "first b"), (logging.WARNING, "c")]
