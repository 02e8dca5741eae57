"""Live progress of a search flight: move, targets found, time, position uncertainty.

On a terminal it is one rich progress bar redrawn in place; in a log (a pipe, CI) it is one
plain line per decision, flushed, so a supervisor sees the flight move as it happens."""

from __future__ import annotations

import sys
from types import TracebackType

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from autopilot_bridge.service.policy_service import Progress as Step


class FlightProgress:
    def __init__(self, label: str = "search", console: Console | None = None) -> None:
        self.console = console or Console(stderr=False)
        self.label = label
        self.live = self.console.is_terminal
        self._bar: Progress | None = None
        self._task = None
        self.last: Step | None = None

    def __enter__(self) -> FlightProgress:
        if self.live:
            self._bar = Progress(
                TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
                TextColumn("found [green]{task.fields[found]}"), TextColumn("cell {task.fields[cell]}"),
                TextColumn("σ {task.fields[sd]} m"), TimeElapsedColumn(), console=self.console, transient=False)
            self._bar.__enter__()
        return self

    def __call__(self, s: Step) -> None:
        self.last = s
        found = f"{s.found}/{s.n_targets}"
        if self._bar is not None:
            if self._task is None:
                self._task = self._bar.add_task(self.label, total=s.max_moves, found=found, cell=s.cell, sd="")
            self._bar.update(self._task, completed=s.move, found=found, cell=s.cell, sd=f"{s.position_sd_m:.2f}")
        else:
            print(f"{self.label}: move {s.move}/{s.max_moves}  found {found}  cell {s.cell}  "
                  f"t {s.elapsed_s:.1f} s  sigma {s.position_sd_m:.2f} m", flush=True, file=sys.stdout)

    def __exit__(self, et: type[BaseException] | None, ev: BaseException | None, tb: TracebackType | None) -> None:
        if self._bar is not None:
            self._bar.__exit__(et, ev, tb)
