"""Progress of a long command on stderr, so that stdout carries only the results (``--json``)."""

from __future__ import annotations

import sys
import time
from typing import TYPE_CHECKING, TextIO

if TYPE_CHECKING:
    from rich.progress import Progress, TaskID


class StderrProgress:
    """``progress(done, total, what)``: a bar on a terminal, one line per step otherwise (a log
    or a pipe keeps them), always on stderr.

    Parameters
    ----------
    title : str
        What runs, e.g. ``"bench plan"``.
    delay : float, seconds
        Show nothing until the work has taken this long (0: from the first step).
    stream : text file, optional
        Default ``sys.stderr``.
    """

    def __init__(self, title: str, *, delay: float = 0.0, stream: TextIO | None = None):
        self.title = title
        self.delay = delay
        self.stream = stream if stream is not None else sys.stderr
        self.t0 = time.perf_counter()
        self.bar: Progress | None = None
        self.task: TaskID | None = None

    def __call__(self, done: int, total: int, what: str) -> None:
        if time.perf_counter() - self.t0 < self.delay:
            return
        if not self.stream.isatty():
            print(f"{self.title}: [{min(done + 1, total)}/{total}] {what}", file=self.stream, flush=True)
            return
        if self.bar is None or self.task is None:
            # rich loads only when a terminal is there to show a bar
            from rich.console import Console
            from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

            bar = Progress(TextColumn(self.title), BarColumn(), MofNCompleteColumn(),
                           TextColumn("{task.description}"), TimeRemainingColumn(),
                           console=Console(file=self.stream), transient=True)
            bar.start()
            self.bar, self.task = bar, bar.add_task(what, total=total)
        self.bar.update(self.task, completed=done, total=total, description=what)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.stop()
            self.bar = None

    def __enter__(self) -> "StderrProgress":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
