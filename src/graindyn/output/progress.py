"""A progress bar for long runs (rich): simulated time, steps per second and an ETA.
Quiet when the output is not a terminal or when switched off."""
import contextlib
import time

from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn


class _Phase:
    """One bar: simulated time of a phase against its longest duration [s]."""

    def __init__(self, progress, name, sim, duration):
        self.progress = progress
        self.start_time = sim.time
        self.start_step = sim.step
        self.wall = time.perf_counter()
        self.task = progress.add_task(name, total=duration, rate="", now="")

    def update(self, sim):
        elapsed = time.perf_counter() - self.wall
        rate = (sim.step - self.start_step) / elapsed if elapsed > 0 else 0.0
        self.progress.update(self.task, completed=sim.time - self.start_time,
                             now=f"t = {sim.time:.4g} s", rate=f"{rate:,.0f} steps/s")


class _Bars:
    def __init__(self, progress):
        self.progress = progress

    def phase(self, name, sim, duration):
        """A bar for a phase that lasts at most ``duration`` seconds of simulated time."""
        if self.progress is None:
            return None
        return _Phase(self.progress, name, sim, duration)


@contextlib.contextmanager
def progress_bar(show=True):
    """Context giving ``phase(name, sim, duration)`` bars, or None bars when quiet."""
    console = Console(stderr=True)
    if not (show and console.is_terminal):
        yield _Bars(None)
        return
    columns = (TextColumn("{task.description}"), BarColumn(), TextColumn("{task.fields[now]}"),
               TextColumn("{task.fields[rate]}"), TimeRemainingColumn())
    with Progress(*columns, console=console, transient=False) as progress:
        yield _Bars(progress)
