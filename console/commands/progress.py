"""Progress for long runs: a rich bar on a terminal, nothing at all when piped or asked for --json.

`drs calibrate` printed nothing for 23 s on three flights and the nested stability and `drs live
evaluate` ran for minutes in silence. The work reports ``(stage, done, total)`` at its outer loop
only (``predictor.calibration`` takes the callback as a parameter and knows nothing of terminals);
a stage with ``total`` None is a spinner with the elapsed time (loading weather, one sweep). The bar
goes to stderr and vanishes when done, so stdout carries the command's answer alone either way.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TextIO, TypeVar

Tell = Callable[[str, int, int | None], None]
"""``tell(stage, done, total)``: a stage's progress; ``total`` None when it cannot be counted."""
T = TypeVar("T")


def _silent(stage: str, done: int, total: int | None) -> None:
    """Piped, quiet or --json: a script reading the output wants the answer, not a bar."""


@contextmanager
def progress(quiet: bool = False, stream: TextIO | None = None) -> Iterator[Tell]:
    """A ``tell`` that draws on ``stream`` (stderr) when it is a terminal and not ``quiet``."""
    out = sys.stderr if stream is None else stream
    if quiet or not out.isatty():
        yield _silent
        return
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        SpinnerColumn,
        TextColumn,
        TimeElapsedColumn,
    )

    columns = (
        SpinnerColumn(),
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
    )
    with Progress(*columns, console=Console(file=out), transient=True) as bar:
        tasks = {}

        def tell(stage: str, done: int, total: int | None) -> None:
            if stage not in tasks:
                tasks[stage] = bar.add_task(stage, total=total)
            bar.update(tasks[stage], completed=done, total=total)

        yield tell


def while_saying(tell: Tell, stage: str, work: Callable[[], T]) -> T:
    """One uncountable step (loading weather, a sweep) as a spinner with its elapsed time."""
    tell(stage, 0, None)
    result = work()
    tell(stage, 1, 1)
    return result
