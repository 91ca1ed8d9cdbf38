"""Progress bars of the command line (rich), written to stderr so stdout stays the answer.

One bar per long step: its fraction done (or bytes sent), the stage in words and the time
taken.  On a terminal the bar redraws in place; elsewhere (a pipe, a log, a test) rich writes
its final state once when the step ends.
"""

from __future__ import annotations

from types import TracebackType

from rich.console import Console
from rich.progress import (
    BarColumn,
    DownloadColumn,
    Progress,
    ProgressColumn,
    TaskID,
    TaskProgressColumn,
    TextColumn,
    TimeElapsedColumn,
    TransferSpeedColumn,
)


def stderr_console() -> Console:
    return Console(stderr=True)


class Bar:
    """A progress bar for one step: `update(done, stage)` with done in [0, total].

    Use as a context manager; bytes=True shows done and total as sizes with a speed.
    """

    def __init__(self, title: str, *, total: float = 1.0, bytes: bool = False) -> None:
        columns: list[ProgressColumn | str] = [
            TextColumn("[bold]{task.description}"),
            BarColumn(),
            DownloadColumn() if bytes else TaskProgressColumn(),
        ]
        if bytes:
            columns.append(TransferSpeedColumn())
        columns += [TimeElapsedColumn(), TextColumn("{task.fields[stage]}")]
        self._progress = Progress(*columns, console=stderr_console())
        self._title, self._total = title, total
        self._task: TaskID | None = None

    def __enter__(self) -> Bar:
        self._progress.start()
        self._task = self._progress.add_task(self._title, total=self._total, stage="")
        return self

    def update(self, done: float, stage: str | None = None) -> None:
        assert self._task is not None, "use the bar as a context manager"
        if stage is None:
            self._progress.update(self._task, completed=done)
        else:
            self._progress.update(self._task, completed=done, stage=stage)

    def advance(self, amount: float) -> None:
        assert self._task is not None, "use the bar as a context manager"
        self._progress.advance(self._task, amount)

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        trace: TracebackType | None,
    ) -> None:
        self._progress.stop()
