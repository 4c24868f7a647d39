"""One progress bar for long commands (rich, on stderr so ``--json`` output stays clean)."""

from __future__ import annotations

import contextlib
from typing import Callable, Iterator


@contextlib.contextmanager
def progress(total: int, label: str, enabled: bool = True, transient: bool = False) -> Iterator[Callable[[], None]]:
    """Yield ``tick()``, advancing a bar of ``total`` steps; a no-op when not ``enabled``."""
    if not enabled:
        yield lambda: None
        return
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn(),
                  console=Console(stderr=True), transient=transient) as bar:
        task = bar.add_task(label, total=total)
        yield lambda: bar.advance(task)
