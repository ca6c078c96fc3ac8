"""Parameter sweeps on Dask: one parameter at a time around a reference config, several
seeds per point, each run in its own run directory, one summary at the end.

    sweep = Sweep.load("examples/oedometer_sweep.toml")   # validates every point
    report = run(sweep, "runs/oedometer_sweep")            # LocalCluster by default
    report.exit_code                                       # 0 all finished, 1 some failed

A *point* is (parameter, value, seed); the reference points (the base config unchanged)
are part of every sweep.  A point whose value equals the base value is the reference
run itself (not computed twice).  Layout of the sweep directory:

    sweep.toml, base.toml      verbatim copies of the sweep file and the base config
    points.json                every point: parameter, value, seed, run directory
    reference/seed-1/          one run directory per run (``graindyn run`` layout)
    friction_sliding=0.2/seed-1/
    summary.csv, summary.json  one row per point; mean and std over seeds per value
    (protocol tables and figures, e.g. bauer_vertical.md, figures/hs_eta_vertical.png)

Runs whose config says ``run.backend = "gpu"`` do not go to Dask (unless a scheduler
or client is given): they run in this process as one GPU ensemble (engines/soft/gpu/batch.py), each
run's protocol in its own thread and their chunks launched together, each run giving
the numbers it gives alone.

Running the same command again skips finished runs (results.json present), resumes the
interrupted ones from their last checkpoint and retries the failed ones (error.txt).

A *keep* folder (``run(..., keep=folder)``, ``graindyn sweep --keep``) holds the record
of every finished run (config.toml, meta.json, results.json: what the summaries read,
a few tens of kB a run, without checkpoints, VTK files or series) in the sweep
directory's layout, with the sweep's files and summaries: each run's record is copied
there as the run finishes, and the runs recorded there count as finished in any sweep
directory, on any machine.  It is the part of a sweep worth committing or carrying off
a cluster's scratch disk.

The summary is pluggable per protocol: the protocol class
(``protocols.PROTOCOLS[config.protocol.kind]``) may define
``summarize_sweep(sweep_dir, points)``; it gets the sweep directory and the collected
points (``Point`` with ``status`` and ``results``) and returns the paths it wrote.
"""
import contextlib
import copy
import csv
import dataclasses
import functools
import json
import math
import os
import pathlib
import re
import shutil
import time
import traceback
import uuid
from typing import Any

import numpy as np
from distributed.diagnostics.plugin import WorkerPlugin

from .config import ConfigError, load, validate
from .config.models import Config
from .config.sweep import SweepFile, load_sweep_file

CONNECT_TIMEOUT = "20s"           # to a scheduler given by address
REFERENCE = "reference"
ERROR_FILE = "error.txt"
RESULTS_FILE = "results.json"
RECORD = ("config.toml", "meta.json", RESULTS_FILE)    # a finished run's record (keep)


class SweepInterrupted(RuntimeError):
    """The sweep was stopped (Ctrl-C); rerunning the same command continues it."""


@dataclasses.dataclass
class Point:
    """One point of a sweep: the base config with ``parameter`` set to ``value``, run
    with ``seed``.  Reference points have ``parameter`` None.  ``name`` is the run
    directory relative to the sweep directory; points whose value equals the base value
    share the reference run's ``name``."""

    parameter: str | None
    label: str
    value: Any
    display: Any
    base_value: Any
    seed: int
    name: str
    config: Config = dataclasses.field(repr=False, compare=False)
    status: str = "pending"           # pending | finished | failed (after collect)
    results: dict | None = dataclasses.field(default=None, repr=False, compare=False)
    error: str | None = None
    directory: pathlib.Path | None = None

    @property
    def is_reference(self):
        """True for the points whose run is the reference run."""
        return self.name.split("/")[0] == REFERENCE

    @property
    def group(self):
        """(parameter, value key) shared by the seeds of one sweep value."""
        return (self.parameter, json.dumps(self.value))


# ---------------------------------------------------------------- names and paths
def _resolve(data, parameter):
    """(container, key) of the dotted ``parameter`` in the config dict ``data``; list
    items are found by their ``name`` (materials.sand) or index.  ValueError saying
    where the path goes wrong."""
    node, where = data, []
    parts = parameter.split(".")
    for k, part in enumerate(parts):
        here = ".".join(where) or "the config"
        if isinstance(node, dict):
            if part not in node:
                raise ValueError(f"{here} has no field {part!r}; its fields are "
                                 f"{', '.join(sorted(node))}")
            key = part
        elif isinstance(node, list) and node and all(isinstance(x, dict) for x in node):
            names = [x.get("name") for x in node]
            if part in names:
                key = names.index(part)
            elif part.isdigit() and int(part) < len(node):
                key = int(part)
            else:
                known = [n for n in names if n is not None]
                raise ValueError(f"{here} has no item {part!r}; items are "
                                 + (", ".join(known) if known else f"0..{len(node) - 1}"))
        else:
            raise ValueError(f"{here} is a value, not a section: it has no {part!r}")
        if k == len(parts) - 1:
            target = node[key]
            if isinstance(target, dict) or (isinstance(target, list) and target
                                            and isinstance(target[0], dict)):
                raise ValueError(f"{parameter} is a section, not a value: name one of its "
                                 "fields")
            return node, key
        where.append(part)
        node = node[key]
        if node is None:
            raise ValueError(f"{'.'.join(where)} is not set in the base config")
    raise ValueError("empty parameter")


def value_text(value):
    """A short, exact text of a value: 0.2, 1.125e8, 1e-6, true, hertz, 0,0,-1.62."""
    if isinstance(value, bool):
        text = "true" if value else "false"
    elif isinstance(value, int):
        text = str(value)
    elif isinstance(value, float):
        if not np.isfinite(value):        # refused when the point's config is checked
            text = str(value)
        elif value == 0 or 1e-4 <= abs(value) < 1e6:
            text = np.format_float_positional(value, unique=True, trim="-")
        else:
            mantissa, exponent = np.format_float_scientific(
                value, unique=True, trim="-").split("e")
            text = f"{mantissa}e{int(exponent)}"
    elif isinstance(value, (list, tuple)):
        text = ",".join(value_text(v) for v in value)
    else:
        text = str(value)
    return text


def safe_name(text, limit=80):
    """``text`` with every character outside [A-Za-z0-9._,=+-] replaced by '_'."""
    text = re.sub(r"[^A-Za-z0-9._,=+\-]", "_", text).strip(".") or "_"
    if len(text) > limit:
        text = text[:limit - 9] + "~" + uuid.uuid5(uuid.NAMESPACE_URL, text).hex[:8]
    return text


def short_names(parameters):
    """The shortest trailing part of each dotted path that tells it from the others."""
    split = {p: p.split(".") for p in parameters}
    names = {}
    for p, parts in split.items():
        k = 1
        while k < len(parts) and any(q != p and split[q][-k:] == parts[-k:] for q in split):
            k += 1
        names[p] = ".".join(parts[-k:])
    return names


# ---------------------------------------------------------------- the sweep
class Sweep:
    """A validated sweep: the base config, the seeds and every point with its Config.

    ``Sweep.load(path)`` reads the sweep file and the base config and builds and checks
    every point's Config before anything runs; ConfigError lists every problem (each
    invalid value with its point)."""

    def __init__(self, path, spec: SweepFile, base_path, base: Config, points):
        self.path = pathlib.Path(path)
        self.spec = spec
        self.base_path = pathlib.Path(base_path)
        self.base = base
        self.points = points

    @property
    def runs(self):
        """The distinct runs (one per run directory), reference first."""
        seen, runs = set(), []
        for p in self.points:
            if p.name not in seen:
                seen.add(p.name)
                runs.append(p)
        return runs

    def selected(self, seeds=None, points=None):
        """The runs of the seeds ``seeds`` (ints) whose point folder (the run directory's
        first part: "reference", "youngs_modulus=1e9") is one of ``points``; None
        selects every seed or point.  ConfigError names a seed or a point folder that
        the sweep does not have."""
        runs = self.runs
        folders = list(dict.fromkeys(p.name.split("/")[0] for p in runs))
        known = list(dict.fromkeys(p.seed for p in runs))
        unknown = [f"seed {s}" for s in seeds or () if s not in known] + [
            f"point {name!r}" for name in points or () if name not in folders]
        if unknown:
            raise ConfigError(f"{self.path.name} has no {', no '.join(unknown)} (seeds: "
                              f"{', '.join(map(str, known))}; points: {', '.join(folders)})")
        return [p for p in runs if (seeds is None or p.seed in seeds)
                and (points is None or p.name.split("/")[0] in points)]

    @classmethod
    def load(cls, path):
        from .runner import check

        path = pathlib.Path(path)
        spec = load_sweep_file(path)
        base_path = path.parent / spec.base
        if not base_path.is_file():
            raise ConfigError(f"{path}: base = {spec.base!r}: no such config file "
                              f"({base_path})")
        base = load(base_path)
        try:
            check(base)
        except ConfigError as err:
            raise ConfigError(f"{base_path}: {err}") from None
        seeds = spec.seeds if spec.seeds is not None else [base.run.seed]
        data = base.model_dump(mode="json")
        if spec.overrides:
            base, data = _overridden(path, data, spec.overrides)
        problems = []
        points = [Point(None, REFERENCE, None, None, None, seed, f"{REFERENCE}/seed-{seed}",
                        _with(data, None, None, seed)) for seed in seeds]
        reference = {seed: p.config.model_dump() for seed, p in zip(seeds, points)}
        labels = short_names([v.parameter for v in spec.vary])
        for k, vary in enumerate(spec.vary):
            try:
                container, key = _resolve(data, vary.parameter)
            except ValueError as err:
                problems.append(f"vary.{k}.parameter = {vary.parameter!r}: {err}")
                continue
            base_value = container[key]
            folders = []
            for j, value in enumerate(vary.values):
                folder = safe_name(f"{labels[vary.parameter]}={value_text(value)}")
                folders.append(folder if folder not in folders else f"{folder}-{j}")
            for j, value in enumerate(vary.values):
                where = f"vary.{k} {vary.parameter} = {value!r}"
                try:
                    config = _with(data, vary.parameter, value, seeds[0])
                    check(config)
                except ConfigError as err:
                    lines = str(err).splitlines()
                    if lines[0].endswith("problem(s)"):
                        lines = lines[1:]
                    problems += [f"{where}: {line.strip()}" for line in lines]
                    continue
                display = vary.display[j] if vary.display is not None else value
                for seed in seeds:
                    config = _with(data, vary.parameter, value, seed)
                    same = config.model_dump() == reference[seed]
                    name = f"{REFERENCE}/seed-{seed}" if same else f"{folders[j]}/seed-{seed}"
                    points.append(Point(vary.parameter, vary.label or labels[vary.parameter],
                                        value, display, base_value, seed, name, config))
        if problems:
            raise ConfigError(f"{path}: {len(problems)} problem(s)\n  "
                              + "\n  ".join(problems))
        return cls(path, spec, base_path, base, points)


def _overridden(path, data, overrides):
    """The base config (Config, and its dict) with the sweep file's ``overrides``;
    ConfigError naming each override that does not fit."""
    data = copy.deepcopy(data)
    problems = []
    for parameter, value in overrides.items():
        try:
            container, key = _resolve(data, parameter)
        except ValueError as err:
            problems.append(f"overrides.{parameter}: {err}")
            continue
        container[key] = value
    if not problems:
        from .runner import check
        try:
            config = validate(data, "overrides")
            check(config)
            return config, config.model_dump(mode="json")
        except ConfigError as err:
            lines = str(err).splitlines()
            problems += [f"overrides: {line.strip()}" for line in
                         (lines[1:] if lines[0].endswith("problem(s)") else lines)]
    raise ConfigError(f"{path}: {len(problems)} problem(s)\n  " + "\n  ".join(problems))


def _with(data, parameter, value, seed):
    """The Config of ``data`` with ``parameter`` = ``value`` and run.seed = ``seed``."""
    data = copy.deepcopy(data)
    if parameter is not None:
        container, key = _resolve(data, parameter)
        container[key] = value
    data["run"]["seed"] = seed
    source = "point" if parameter is None else f"point {parameter} = {value!r}"
    return validate(data, source)


# ---------------------------------------------------------------- one point (a task)
def finished(directory):
    """The results of the finished run in ``directory``, or None (no results.json, or
    one cut short by a kill: that run resumes from its final checkpoint)."""
    try:
        results = json.loads((pathlib.Path(directory) / RESULTS_FILE).read_text())
    except (OSError, ValueError):
        return None
    return results if isinstance(results, dict) else None


def run_standing(directory, now=None):
    """Where the run in ``directory`` stands, read from its files without changing
    them: a dict with ``state`` "finished" (with ``wall_s``, the wall time of its last
    session [s]), "failed" (``error``: the first line of error.txt), "started" (a log:
    running now, or interrupted and resumable; with what output.rundir.progress reads
    from the log) or "not started"."""
    directory = pathlib.Path(directory)
    results = finished(directory)
    if results is not None:
        return {"state": "finished", "wall_s": results.get("wall_time_this_session_s")}
    error = directory / ERROR_FILE
    if error.exists():
        lines = error.read_text(errors="replace").strip().splitlines()
        return {"state": "failed", "error": lines[0] if lines else ""}
    from .output.rundir import progress

    news = progress(directory, now)
    return {"state": "not started"} if news is None else {"state": "started", **news}


def standing(sweep: "Sweep", out, keep=None, now=None):
    """Where each run of ``sweep`` stands (run_standing) in the sweep directory ``out``,
    a run recorded as finished in the keep folder ``keep`` counting as finished
    (``kept`` true when only there); nothing runs, nothing is written.  A list of
    dicts in the sweep's order, each with the run's ``name``."""
    out = pathlib.Path(out)
    rows = []
    for p in sweep.runs:
        row = run_standing(out / p.name, now)
        if row["state"] != "finished" and keep is not None:
            kept = finished(pathlib.Path(keep) / p.name)
            if kept is not None:
                row = {"state": "finished", "wall_s": kept.get("wall_time_this_session_s"),
                       "kept": True}
        rows.append({"name": p.name, **row})
    return rows


def _quiet(*args, **kwargs):
    pass


def _has_checkpoint(directory):
    from .output import checkpoint

    folder = pathlib.Path(directory) / "checkpoints"
    return (folder / checkpoint.LATEST).exists() or (folder / checkpoint.PREVIOUS).exists()


def _clear(directory):
    """Remove what a run left before its first checkpoint (nothing worth keeping)."""
    directory = pathlib.Path(directory)
    if not directory.exists():
        return
    names = {p.name for p in directory.iterdir()}
    if names - {"config.toml", "meta.json", "run.log", "series.csv", "vtk", "figures",
                "checkpoints", ERROR_FILE}:
        raise FileExistsError(f"{directory} holds files that are not a graindyn run: "
                              "move them away or choose another --out")
    shutil.rmtree(directory)


def run_point(config: Config, directory, threads=1):
    """Run one point in ``directory`` (the Dask task): skip it if results.json exists,
    resume it if it has a checkpoint, start it otherwise.  numba uses ``threads``
    threads.  Never raises: a failure writes error.txt (message and traceback) and is
    returned as {"status": "failed", "error": message}."""
    from . import runner
    from .output.checkpoint import CheckpointError

    directory = pathlib.Path(directory)
    start = time.perf_counter()
    if finished(directory):
        return {"status": "finished", "how": "finished earlier", "seconds": 0.0}
    how = "started"
    try:
        (directory / ERROR_FILE).unlink(missing_ok=True)
        if _has_checkpoint(directory):
            try:
                runner.resume(directory, show_progress=False, echo=_quiet, threads=threads)
                how = "resumed"
            except CheckpointError:
                how = "restarted (its checkpoints were unusable)"
        if how != "resumed":
            _clear(directory)
            config = config.model_copy(deep=True)
            config.run.threads = threads
            runner.execute(config, directory, show_progress=False, echo=_quiet)
    except Exception as err:  # any failure of one point is recorded, never propagated
        message = f"{type(err).__name__}: {err}"
        directory.mkdir(parents=True, exist_ok=True)
        (directory / ERROR_FILE).write_text(f"{message}\n\n{traceback.format_exc()}")
        return {"status": "failed", "how": how, "error": message,
                "seconds": time.perf_counter() - start}
    return {"status": "finished", "how": how, "seconds": time.perf_counter() - start}


# ---------------------------------------------------------------- keep folder
def restore_records(sweep: Sweep, out, keep):
    """Copy into the sweep directory ``out`` the records of the runs finished in the
    keep folder ``keep`` that ``out`` does not hold finished (an unfinished run there is
    replaced); returns how many.  ConfigError, before anything is copied, if a record
    there is of another config than the sweep's point."""
    out, keep = pathlib.Path(out), pathlib.Path(keep)
    kept = [p for p in sweep.runs if finished(keep / p.name) and not finished(out / p.name)]
    problems = [line for line in (_mismatch(p, keep / p.name) for p in kept) if line]
    if problems:
        raise ConfigError(f"--keep {keep}: {len(problems)} record(s) do not match the "
                          "sweep:\n  " + "\n  ".join(problems))
    for p in kept:
        target = out / p.name
        if target.exists():
            if not (target / "config.toml").exists() and any(target.iterdir()):
                raise FileExistsError(f"{target} holds files that are not a graindyn run: "
                                      "move them away or choose another --out")
            shutil.rmtree(target)
        keep_record(keep / p.name, target)
    return len(kept)


def keep_record(directory, target):
    """Copy the record (RECORD) of the finished run in ``directory`` into ``target``,
    results.json last, so that a copy cut short never looks finished."""
    target = pathlib.Path(target)
    target.mkdir(parents=True, exist_ok=True)
    for name in RECORD:
        source = pathlib.Path(directory) / name
        if source.exists():
            shutil.copyfile(source, target / name)


def keep_sweep_files(out, keep, paths=()):
    """Copy the sweep's own files (sweep.toml, base.toml, points.json) and the
    summaries ``paths`` (within ``out``) into the keep folder, in the same places."""
    out, keep = pathlib.Path(out), pathlib.Path(keep)
    for path in [out / "sweep.toml", out / "base.toml", out / "points.json", *paths]:
        path = pathlib.Path(path)
        if path.is_file() and path.is_relative_to(out):
            target = keep / path.relative_to(out)
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(path, target)


# ---------------------------------------------------------------- running
def _stored_differences(point, stored):
    """Fields where the run stored in a point's directory differs from the point's
    config, leaving out what the runner fills in (dt, skin) and the threads."""
    a, b = point.config.model_dump(mode="json"), stored.model_dump(mode="json")
    a["run"].pop("threads"), b["run"].pop("threads")
    for name in ("dt", "skin"):
        if a["engine"][name] is None:
            a["engine"].pop(name), b["engine"].pop(name)
    out = []

    def walk(x, y, where):
        if isinstance(x, dict) and isinstance(y, dict):
            for key in sorted(set(x) | set(y)):
                walk(x.get(key), y.get(key), f"{where}.{key}" if where else key)
        elif isinstance(x, list) and isinstance(y, list) and len(x) == len(y):
            for k, (u, v) in enumerate(zip(x, y)):
                walk(u, v, f"{where}.{k}")
        elif x != y:
            out.append(f"{where}: {y!r} there, {x!r} in the sweep")
    walk(a, b, "")
    return out


def _mismatch(point, folder):
    """A line naming ``folder`` when the run stored there (its config.toml) is of
    another config than ``point``'s, else None."""
    try:
        differences = _stored_differences(point, load(pathlib.Path(folder) / "config.toml"))
    except (ConfigError, OSError) as err:
        differences = [str(err).splitlines()[0]]
    if differences:
        return f"{folder} holds a run of another config (" + "; ".join(differences[:3]) + ")"
    return None


def prepare(sweep: Sweep, out):
    """Create the sweep directory (copies of the sweep file and base config, points.json)
    and check that the runs already there belong to this sweep; ConfigError if not."""
    out = pathlib.Path(out)
    problems = [line for line in (_mismatch(p, out / p.name) for p in sweep.runs
                                  if (out / p.name / "config.toml").exists()) if line]
    if problems:
        raise ConfigError(f"{out}: {len(problems)} run director(ies) do not match the sweep "
                          "(remove them or choose another --out):\n  " + "\n  ".join(problems))
    out.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(sweep.path, out / "sweep.toml")
    shutil.copyfile(sweep.base_path, out / "base.toml")
    (out / "points.json").write_text(json.dumps(
        [{"parameter": p.parameter, "label": p.label, "value": p.value,
          "display": p.display, "seed": p.seed, "directory": p.name} for p in sweep.points],
        indent=1))


def _local_cores():
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


class _IgnoreInterrupt(WorkerPlugin):
    """Worker plugin of the local cluster: Ctrl-C in the terminal reaches every process
    of the group; the workers leave it to the sweep command, which stops them."""

    def setup(self, worker):
        import signal
        import threading

        if threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGINT, signal.SIG_IGN)


@contextlib.contextmanager
def _dask_client(scheduler, workers, threads, jobs, client):
    """A Client: the one given, one connected to ``scheduler``, or a LocalCluster of
    processes (one point at a time per worker).  Yields (client, description)."""
    if client is not None:
        yield client, "the given Dask client"
        return
    import logging

    from distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            remote = Client(scheduler, timeout=CONNECT_TIMEOUT)
        except (OSError, TimeoutError, ValueError) as err:
            raise ConfigError(f"--scheduler {scheduler}: cannot connect: {err}") from None
        with remote:
            yield remote, f"the Dask scheduler at {scheduler}"
        return
    n = workers or max(1, _local_cores() // threads)
    n = max(1, min(n, jobs))
    # distributed's logs below CRITICAL silenced: a point that fails comes back
    # through its future (error.txt, the report), and a worker whose last heartbeat
    # races the scheduler's close at the end logs a traceback at ERROR that says nothing
    with LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                      dashboard_address=":0", silence_logs=logging.CRITICAL) as cluster, \
            Client(cluster) as c:
        c.register_plugin(_IgnoreInterrupt(), name="graindyn-ignore-sigint")
        try:
            yield c, (f"a local Dask cluster of {n} worker process(es) x {threads} "
                      "thread(s)" + (f", dashboard {c.dashboard_link}"
                                     if cluster.dashboard_link else ""))
        except BaseException:
            _kill_workers(cluster)
            raise


def _kill_workers(cluster):
    """Stop the local workers now, running points and all: their checkpoints are written
    atomically, so each keeps its last one (a graceful close would wait for them)."""
    import signal

    for nanny in list(cluster.workers.values()):
        pid = getattr(nanny, "pid", None)
        if pid:
            with contextlib.suppress(Exception):
                nanny.close_gracefully(reason="graindyn sweep interrupted")
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGKILL)


def _printer():
    """Lines to the terminal through rich (plain text when not a terminal)."""
    from rich.console import Console

    def echo(text, style=None):
        Console(highlight=False).print(text, style=style, markup=False, soft_wrap=True)
    return echo


@dataclasses.dataclass
class Report:
    """What a sweep did: the runs by status, the summary files, and the exit code."""

    directory: pathlib.Path
    points: list
    runs: list
    paths: list
    summary_error: str | None = None
    wanted: list | None = None       # the names of the runs asked for (None: every run)

    @property
    def finished(self):
        return [p for p in self.runs if p.status == "finished"]

    @property
    def failed(self):
        return [p for p in self.runs if p.status == "failed"]

    @property
    def pending(self):
        return [p for p in self.runs if p.status == "pending"]

    @property
    def exit_code(self):
        """0 when every run asked for finished and the summary was written, 1
        otherwise."""
        asked = [p for p in self.runs if self.wanted is None or p.name in self.wanted]
        return 0 if all(p.status == "finished" for p in asked) and not self.summary_error \
            else 1


def run(sweep: Sweep, out, scheduler=None, workers=None, threads_per_worker=1,
        client=None, echo=None, keep=None, seeds=None, points=None):
    """Run every unfinished point of ``sweep`` into the sweep directory ``out`` on Dask,
    then write the summary; returns the Report.  ``client`` (a distributed.Client) wins
    over ``scheduler`` (an address), which wins over a LocalCluster of ``workers``
    processes.  ``echo(text)`` gets one line per finished point (default: rich).
    ``keep``: a keep folder (module docstring): the runs recorded there are taken as
    finished, and every run that finishes, the sweep's files and the summaries are
    recorded there.  ``seeds``, ``points``: run only the unfinished runs of these seeds
    and point folders (Sweep.selected), in the same sweep directory; the summary covers
    every finished run.  SweepInterrupted on Ctrl-C (after the running points were
    cancelled)."""
    import numba

    say = _printer() if echo is None else (lambda text, style=None: echo(text))
    out = pathlib.Path(out).resolve()
    threads = int(threads_per_worker)
    if threads < 1:
        raise ConfigError(f"--threads-per-worker = {threads}: must be >= 1")
    if scheduler is None and client is None and threads > numba.config.NUMBA_NUM_THREADS:
        raise ConfigError(f"--threads-per-worker = {threads}: this machine offers at most "
                          f"{numba.config.NUMBA_NUM_THREADS}")
    wanted = None
    if seeds is not None or points is not None:
        wanted = {p.name for p in sweep.selected(seeds, points)}
    todo = _open(sweep, out, keep, say, "to run", wanted)
    batched = [p for p in todo if p.config.run.backend == "gpu"] \
        if scheduler is None and client is None else []
    todo = [p for p in todo if p not in batched]
    if batched:
        _run_batched(batched, out, threads, say, keep)
    if todo:
        with _dask_client(scheduler, workers, threads, len(todo), client) as (c, where):
            say(f"running on {where}")
            _submit_all(c, todo, out, threads, say, keep)
    report = finish(sweep, out, say, wanted)
    if keep is not None:
        keep_sweep_files(out, keep, report.paths)
    return report


def run_order(todo, out, seeds):
    """The order the unfinished runs ``todo`` are started in: those with a checkpoint
    in ``out`` first (interrupted: they resume), then seed by seed (every point's first
    seed before any point's second), each in the sweep file's order.  A long sweep
    stopped part way then has every point with a seed or two rather than some points
    with all of their seeds and others with none."""
    rank = {seed: k for k, seed in enumerate(seeds)}
    return [p for _, p in sorted(enumerate(todo), key=lambda item: (
        not _has_checkpoint(out / item[1].name), rank.get(item[1].seed, 0), item[0]))]


def _open(sweep: Sweep, out, keep, say, what, wanted=None):
    """Make the sweep directory ``out`` ready (the records of ``keep`` brought in,
    prepare, the finished runs recorded in ``keep``), say how many runs are finished,
    and return the others (of those named in ``wanted``, if given)."""
    restored = restore_records(sweep, out, keep) if keep is not None else 0
    prepare(sweep, out)
    runs = sweep.runs
    if keep is not None:
        keep = pathlib.Path(keep)
        for p in runs:
            if finished(out / p.name) and not finished(keep / p.name):
                keep_record(out / p.name, keep / p.name)
        keep_sweep_files(out, keep)
    todo = run_order([p for p in runs if not finished(out / p.name)], out,
                     list(dict.fromkeys(p.seed for p in sweep.points)))
    left = len(todo)
    if wanted is not None:
        todo = [p for p in todo if p.name in wanted]
    say(f"sweep {sweep.path.name}: {len(runs)} runs ({len(sweep.points)} points), "
        f"{len(runs) - left} finished earlier"
        + (f" ({restored} of them taken from {keep})" if restored else "")
        + (f", {len(todo)} of the {left} others selected" if wanted is not None else "")
        + f", {len(todo)} {what}, into {out}")
    return todo


def summarize(sweep: Sweep, out, keep=None, echo=None):
    """The summaries of the runs of ``sweep`` finished so far in ``out`` (and in the
    keep folder ``keep``), written as a finished sweep writes them; nothing runs.
    Returns the Report (the unfinished runs pending)."""
    say = _printer() if echo is None else (lambda text, style=None: echo(text))
    out = pathlib.Path(out).resolve()
    _open(sweep, out, keep, say, "not finished (not run: --summarize)")
    report = finish(sweep, out, say)
    if keep is not None:
        keep_sweep_files(out, keep, report.paths)
    return report


def _say_outcome(say, head, p, outcome, out, keep=None):
    """One line for a run that ended; a finished one's record goes to ``keep``."""
    if outcome["status"] == "finished":
        if keep is not None:
            keep_record(out / p.name, pathlib.Path(keep) / p.name)
        say(f"{head} finished {p.name} ({outcome['how']}, {outcome['seconds']:.1f} s)",
            style="green")
    else:
        say(f"{head} FAILED {p.name}: {outcome['error']} (see "
            f"{out / p.name / ERROR_FILE})", style="bold red")


def _run_batched(todo, out, threads, say, keep=None):
    """Runs with backend gpu, all in this process as one ensemble on the GPU
    (engines/soft/gpu/batch.py: each run's protocol in its own thread, their chunks launched
    together); each gets the numbers it gets alone."""
    from .engines.soft.gpu.batch import Batch

    say(f"running {len(todo)} run(s) with backend gpu together, as one GPU ensemble")
    jobs = [functools.partial(run_point, p.config, str(out / p.name), threads)
            for p in todo]
    ended = []

    def done(index, outcome):
        ended.append(index)
        _say_outcome(say, f"[{len(ended)}/{len(todo)}]", todo[index], outcome, out, keep)

    batch = Batch()
    try:
        batch.run(jobs, done)
    except KeyboardInterrupt:
        raise SweepInterrupted(
            f"interrupted after {len(ended)} of {len(todo)} runs: the running ones keep "
            "their last checkpoint; rerun the same command to continue") from None
    say(f"the GPU ensemble ran {batch.rounds} rounds of chunks")


def _submit_all(client, todo, out, threads, say, keep=None):
    from distributed import as_completed

    token = uuid.uuid4().hex[:8]
    futures = {}
    for k, p in enumerate(todo):
        future = client.submit(run_point, p.config, str(out / p.name), threads,
                               key=f"graindyn-sweep-{token}-{k}", pure=False,
                               priority=len(todo) - k, retries=0)
        futures[future] = p
    done = 0
    try:
        for future in as_completed(futures):
            p = futures[future]
            outcome = _outcome(future, out / p.name)
            done += 1
            _say_outcome(say, f"[{done}/{len(todo)}]", p, outcome, out, keep)
    except KeyboardInterrupt:
        client.cancel(list(futures))
        raise SweepInterrupted(
            f"interrupted after {done} of {len(todo)} runs: the running ones keep their last "
            "checkpoint; rerun the same command to continue") from None


def _outcome(future, directory):
    """The task's outcome dict; a task that died (worker lost) is recorded here."""
    if future.status == "finished":
        return future.result()
    try:
        err = future.exception()
        message = f"{type(err).__name__}: {err}"
        trace = "".join(traceback.format_tb(future.traceback()))
    except Exception as other:  # a cancelled future has no exception to show
        message, trace = f"{future.status}: {other}", ""
    directory.mkdir(parents=True, exist_ok=True)
    (directory / ERROR_FILE).write_text(f"{message}\n\n{trace}")
    return {"status": "failed", "error": message, "seconds": 0.0}


# ---------------------------------------------------------------- collecting, summary
def collect(sweep: Sweep, out):
    """Copies of every point of ``sweep`` with ``directory``, ``status`` (finished,
    failed or pending), ``results`` and ``error`` read from the sweep directory."""
    out = pathlib.Path(out)
    points = []
    for p in sweep.points:
        directory = out / p.name
        status, results, error = "pending", finished(directory), None
        if results is not None:
            status = "finished"
        elif (directory / ERROR_FILE).exists():
            status = "failed"
            error = (directory / ERROR_FILE).read_text().split("\n\n")[0].strip()
        points.append(dataclasses.replace(p, status=status, results=results, error=error,
                                          directory=directory))
    return points


def flatten(results, prefix=""):
    """Scalar results as {"a.b.c": value} (numbers and booleans; lists and text left
    out): {"bauer": {"vertical": {"h_s_Pa": 1e7}}} -> {"bauer.vertical.h_s_Pa": 1e7}."""
    out = {}
    for key, value in results.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(flatten(value, name + "."))
        elif isinstance(value, (bool, int, float)) and value is not None:
            out[name] = value
    return out


def groups(points):
    """The points grouped by (parameter, value), in sweep order, reference first."""
    out = {}
    for p in points:
        out.setdefault(p.group, []).append(p)
    return list(out.values())


def statistics(points):
    """Mean, sample standard deviation (ddof = 1; None with one seed) and count over the
    finished points of every numeric (not boolean) scalar result; non-finite values are
    left out."""
    values = {}
    for p in points:
        if p.status != "finished":
            continue
        for key, v in flatten(p.results).items():
            if not isinstance(v, bool) and math.isfinite(v):
                values.setdefault(key, []).append(float(v))
    mean = {k: float(np.mean(v)) for k, v in values.items()}
    std = {k: float(np.std(v, ddof=1)) if len(v) > 1 else None for k, v in values.items()}
    return mean, std, {k: len(v) for k, v in values.items()}


def _cell(value):
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, (list, tuple, dict)):
        return json.dumps(value)
    return str(value)


def write_summary(out, points, sweep_name="", protocol=""):
    """summary.csv (one row per point, results flattened) and summary.json (per
    parameter value: mean and std over seeds of every numeric result); their paths."""
    out = pathlib.Path(out)
    fixed = ["parameter", "label", "value", "display", "seed", "status", "directory",
             "error"]
    columns = []
    for p in points:
        for key in flatten(p.results or {}):
            if key not in columns:
                columns.append(key)
    with open(out / "summary.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(fixed + columns)
        for p in points:
            flat = flatten(p.results or {})
            writer.writerow([_cell(x) for x in (
                p.parameter or REFERENCE, p.label, p.value, p.display, p.seed, p.status,
                p.name, p.error)] + [_cell(flat.get(c)) for c in columns])
    runs = {p.name: p.status for p in points}
    summary = {"sweep": sweep_name, "protocol": protocol,
               "runs": {s: sum(1 for v in runs.values() if v == s)
                        for s in ("finished", "failed", "pending")},
               "groups": []}
    for members in groups(points):
        first = members[0]
        mean, std, count = statistics(members)
        summary["groups"].append({
            "parameter": first.parameter, "label": first.label, "value": first.value,
            "display": first.display, "base_value": first.base_value,
            "seeds": [p.seed for p in members],
            "directories": [p.name for p in members],
            "finished": sum(p.status == "finished" for p in members),
            "failed": [p.name for p in members if p.status == "failed"],
            "pending": [p.name for p in members if p.status == "pending"],
            "mean": mean, "std": std, "count": count})
    (out / "summary.json").write_text(json.dumps(summary, indent=1))
    return [out / "summary.csv", out / "summary.json"]


def summary_hook(kind):
    """The protocol's sweep summary function (its ``summarize_sweep``), or None."""
    from .protocols import PROTOCOLS

    return getattr(PROTOCOLS.get(kind), "summarize_sweep", None)


def finish(sweep: Sweep, out, say=None, wanted=None):
    """Collect the points, write the summaries (general and protocol), say what failed;
    returns the Report (``wanted``: the names of the runs asked for, Report.wanted)."""
    say = say or (lambda text, style=None: print(text))
    out = pathlib.Path(out)
    points = collect(sweep, out)
    kind = sweep.base.protocol.kind
    paths = write_summary(out, points, sweep.path.name, kind)
    summary_error = None
    hook = summary_hook(kind)
    if hook is not None:
        try:
            paths += [pathlib.Path(p) for p in hook(out, points) or []]
        except Exception as err:  # the runs are safe; only this summary is missing
            summary_error = f"{type(err).__name__}: {err}"
            (out / "summary_error.txt").write_text(f"{summary_error}\n\n"
                                                   f"{traceback.format_exc()}")
            say(f"the {kind} summary failed: {summary_error} (see "
                f"{out / 'summary_error.txt'})", style="bold red")
        else:
            (out / "summary_error.txt").unlink(missing_ok=True)
    seen, runs = set(), []
    for p in points:
        if p.name not in seen:
            seen.add(p.name)
            runs.append(p)
    report = Report(out, points, runs, paths, summary_error,
                    None if wanted is None else sorted(wanted))
    say(f"{len(report.finished)} of {len(runs)} runs finished; summary: "
        + ", ".join(str(p.relative_to(out)) if p.is_relative_to(out) else str(p)
                    for p in paths))
    if report.failed:
        say(f"{len(report.failed)} run(s) failed (rerun the same command to retry them):",
            style="bold red")
        for p in report.failed:
            say(f"  {p.name}: {p.error}", style="red")
    if report.pending:
        say(f"{len(report.pending)} run(s) did not run: "
            + ", ".join(p.name for p in report.pending), style="yellow")
    return report
