"""The run directory: everything a run leaves behind, in one folder.

    config.toml      the resolved config (every default filled in)
    meta.json        graindyn version, git commit, seed, machine, threads, backend, start
    run.log          what happened, with times
    series.csv       time series, units in the column names
    results.json     the scalar results
    figures/*.png    the figures (``graindyn plot`` redraws them from the files above)
    vtk/*.vtu, *.pvd snapshots for ParaView / OVITO
    checkpoints/     checkpoint.h5 (latest) and checkpoint.prev.h5
"""
import csv
import datetime
import json
import logging
import os
import pathlib
import platform
import re
import subprocess
import sys
import time

import numba
import numpy as np

from .. import __version__


def git_commit():
    """The commit of the graindyn source tree, if it is a git checkout (else None)."""
    here = pathlib.Path(__file__).resolve().parents[3]
    try:
        out = subprocess.run(["git", "-C", str(here), "rev-parse", "HEAD"],
                             capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip() if out.returncode == 0 else None


def machine():
    """Host, CPU, cores and software versions."""
    return {"host": platform.node(), "cpu": platform.processor() or platform.machine(),
            "cores": os.cpu_count(), "python": sys.version.split()[0],
            "numpy": np.__version__, "numba": numba.__version__,
            "platform": platform.platform()}


# a line of run.log (RunDirectory.log): "2026-12-06 01:24:41,034 checkpoint at t = 0 s ..."
_LOG_LINE = re.compile(r"^(\d{4}-\d\d-\d\d \d\d:\d\d:\d\d),\d+ (.*)$")
_SIMULATED = re.compile(r"\bt = ([-+0-9.eE]+) s\b")


def _log_entries(path):
    """The lines of a run.log as (wall-clock time [s since the epoch], text), the lines
    the logger did not write left out."""
    entries = []
    try:
        text = pathlib.Path(path).read_text(errors="replace")
    except OSError:
        return entries
    for line in text.splitlines():
        match = _LOG_LINE.match(line)
        if match:
            stamp = time.mktime(time.strptime(match[1], "%Y-%m-%d %H:%M:%S"))
            entries.append((stamp, match[2]))
    return entries


def progress(path, now=None):
    """How far the run in the run directory ``path`` has gone, read from its run.log
    alone (running now, or interrupted): None without a log, else a dict with
    ``simulated_s`` (the last simulated time the log names [s], None if none),
    ``news`` (its last line that is not a checkpoint: the phase, level, cycle or
    avalanche it is in), ``quiet_s`` (how long ago the log was written [s]) and
    ``rate`` (simulated seconds per wall-clock hour between its last two checkpoints
    of one session; None with fewer)."""
    log = pathlib.Path(path) / "run.log"
    entries = _log_entries(log)
    if not entries:
        return None
    simulated = [float(m[1]) for _, text in entries if (m := _SIMULATED.search(text))]
    news = [text for _, text in entries if not text.startswith("checkpoint")]
    marks = []
    for stamp, text in entries:
        if text.startswith(("start", "resume")):
            marks = []                    # a new session: its clock starts afresh
        elif text.startswith("checkpoint") and (m := _SIMULATED.search(text)):
            marks.append((stamp, float(m[1])))
    rate = None
    if len(marks) >= 2 and marks[-1][0] > marks[-2][0]:
        rate = 3600.0 * (marks[-1][1] - marks[-2][1]) / (marks[-1][0] - marks[-2][0])
    now = time.time() if now is None else now
    return {"simulated_s": simulated[-1] if simulated else None,
            "news": news[-1] if news else "", "quiet_s": now - log.stat().st_mtime,
            "rate": rate}


class RunDirectory:
    """A run's folder; ``create`` starts a new one, the constructor opens an existing one."""

    def __init__(self, path):
        self.path = pathlib.Path(path)
        self.figures = self.path / "figures"
        self.vtk = self.path / "vtk"
        self.checkpoints = self.path / "checkpoints"
        self.logger = logging.getLogger(f"graindyn.run.{self.path.resolve()}")
        if not self.logger.handlers and self.path.exists():
            # opened on the first line logged, so reading a run back changes nothing
            handler = logging.FileHandler(self.path / "run.log", delay=True)
            handler.setFormatter(logging.Formatter("%(asctime)s %(message)s"))
            self.logger.addHandler(handler)
            self.logger.setLevel(logging.INFO)
            self.logger.propagate = False

    @classmethod
    def create(cls, path, config_toml, meta):
        """A new run directory; FileExistsError if ``path`` already holds a run."""
        path = pathlib.Path(path)
        if (path / "config.toml").exists():
            raise FileExistsError(f"{path} already holds a run: resume it with "
                                  f"'graindyn run --resume {path}' or choose another --out")
        path.mkdir(parents=True, exist_ok=True)
        (path / "config.toml").write_text(config_toml)
        meta = {"version": __version__, "git_commit": git_commit(), "machine": machine(),
                "started": datetime.datetime.now().isoformat(timespec="seconds"), **meta}
        (path / "meta.json").write_text(json.dumps(meta, indent=1))
        return cls(path)

    def log(self, message):
        """Append one line to run.log."""
        self.logger.info(message)

    def close(self):
        """Release the log file."""
        for handler in list(self.logger.handlers):
            handler.close()
            self.logger.removeHandler(handler)

    def meta(self):
        """The meta.json of the run."""
        return json.loads((self.path / "meta.json").read_text())

    def write_results(self, results):
        """results.json (scalars and small lists)."""
        (self.path / "results.json").write_text(json.dumps(results, indent=1, default=float))

    def results(self):
        """The results.json of a finished run."""
        path = self.path / "results.json"
        if not path.exists():
            raise FileNotFoundError(f"{path}: the run has not finished (no results yet)")
        return json.loads(path.read_text())


class Series:
    """A CSV time series with units in the column names ("time [s]"), written row by row
    and flushed, so an interrupted run keeps what it wrote."""

    def __init__(self, path):
        self.path = pathlib.Path(path)
        self.columns = None

    def append(self, row: dict):
        """Add a row (column name with unit -> value); the first row fixes the columns."""
        new = not self.path.exists()
        if self.columns is None:
            self.columns = list(row) if new else self.path.open().readline().strip().split(",")
        with self.path.open("a", newline="") as f:
            writer = csv.writer(f)
            if new:
                writer.writerow(self.columns)
            writer.writerow([repr(float(row[c])) for c in self.columns])

    def truncate(self, time):
        """Drop the rows after simulated ``time`` [s] (column "time [s]", written as
        repr of the float: read back exactly): used when resuming."""
        if not self.path.exists():
            return
        with self.path.open(newline="") as f:
            rows = list(csv.reader(f))
        k = rows[0].index("time [s]")
        keep = [rows[0]] + [r for r in rows[1:] if float(r[k]) <= time]
        with self.path.open("w", newline="") as f:
            csv.writer(f).writerows(keep)

    def read(self):
        """The series as {column: array}."""
        data = np.genfromtxt(self.path, delimiter=",", names=None, skip_header=1, ndmin=2)
        header = self.path.open().readline().strip().split(",")
        return {c: data[:, k] for k, c in enumerate(header)}
