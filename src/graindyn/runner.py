"""Running a config: a run directory in, results out, nothing lost on interruption.

``execute(config, out)`` starts a run, ``resume(out)`` continues one from its last
checkpoint.  Between compiled chunks the driver records the time series, writes VTK
snapshots, shows progress and writes checkpoints (every ``checkpoint_every_steps`` steps
or ``checkpoint_every_seconds`` of wall-clock time, at each phase end, and on SIGINT or
SIGTERM, after which it raises RunInterrupted).  Chunks end on the same steps whether
or not the run is cut, so a resumed run gives the same numbers to the last bit as an
uninterrupted one (same backend and thread count).
"""
import json
import math
import pathlib
import signal
import threading
import time

import numba
import numpy as np

from . import _threads as threading_policy
from .config import ConfigError, build, dumps, load
from .config.models import Config
from .core.state import State
from .core.triggers import Periodic
from .engines import ENGINES
from .output import checkpoint
from .output.progress import progress_bar
from .output.rundir import RunDirectory, Series
from .output.writers import NetworkWriter, SeriesWriter, VtkWriter, series_row


class RunInterrupted(RuntimeError):
    """A run stopped by a signal after writing its checkpoint."""

    def __init__(self, signum, rundir, time):
        self.signum, self.rundir, self.time = signum, rundir, time
        super().__init__(f"interrupted by {signal.Signals(signum).name} at t = {time:.6g} s; "
                         f"checkpoint written: resume with 'graindyn run --resume {rundir}'")

    def __reduce__(self):
        # a run in a worker process (a study's jobs) hands it back to the parent
        return (type(self), (self.signum, self.rundir, self.time))


def check(config: Config):
    """Everything about a config that can be checked without simulating: the contact
    model against the materials (for an engine that reads it), the time step, the
    backend.  ConfigError otherwise; returns the time-step report."""
    if ENGINES[config.engine.kind].contact_laws:
        try:
            build.contact_model(config).pair_table(build.materials(config))
        except ValueError as err:
            raise ConfigError(f"contact: {err}") from None
    if config.run.backend == "gpu":
        from .engines.soft.gpu import unavailable
        reason = unavailable()
        if reason:
            raise ConfigError(f"run.backend = 'gpu': {reason}; use backend = 'cpu'")
    return build.check_time_step(config)


class _Signals:
    """SIGINT/SIGTERM set a flag instead of killing the run (main thread only)."""

    def __init__(self):
        self.received = None
        self.saved = {}

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self.saved[sig] = signal.signal(sig, self._handle)
        return self

    def _handle(self, signum, frame):
        self.received = signum

    def __exit__(self, *exc):
        for sig, handler in self.saved.items():
            signal.signal(sig, handler)


class _Driver:
    """The between-chunk work of one run: writers, progress, checkpoints."""

    def __init__(self, rundir, protocol, engine, rng, progress_state, output, show):
        self.rundir, self.protocol, self.engine, self.rng = rundir, protocol, engine, rng
        protocol.log = rundir.log
        protocol.folder = rundir.path
        self.state = progress_state
        self.writers = [SeriesWriter(rundir.path / "series.csv",
                                     Periodic(time=output.series_every), self.series_row),
                        VtkWriter(rundir.vtk, None if output.vtk_every is None
                                  else Periodic(time=output.vtk_every), output.vtk_contacts)]
        if output.figures:
            self.writers.append(NetworkWriter(rundir.figures, None if output.pictures_every
                                              is None else Periodic(time=output.pictures_every),
                                              protocol.title))
        self.every = [(w.trigger, w.write) for w in self.writers if w.trigger is not None]
        self.figures = output.figures
        self.every_steps = output.checkpoint_every_steps or math.inf
        self.every_seconds = output.checkpoint_every_seconds or math.inf
        self.last_step = engine.step
        self.last_time = time.monotonic()
        self.show = show
        self.signals = None
        self.bar = None

    def series_row(self, engine):
        """A row of series.csv: the standard columns, then the protocol's own."""
        return series_row(engine) | self.protocol.series_columns(engine)

    def resume(self, meta, t):
        """Hand each writer its state from the checkpoint ``meta`` at time ``t`` [s]."""
        states = meta.get("writers", {})
        if "writers" not in meta and "vtk" in meta:      # a checkpoint of an older version
            states = {"vtk": {"entries": meta["vtk"]}}
        for w in self.writers:
            w.resume(states.get(w.name, {}), t)

    def write_all(self, engine):
        """Every writer now, whatever its trigger (the start and the end of a run)."""
        for w in self.writers:
            w.write(engine)

    def write_checkpoint(self):
        engine = self.engine
        meta = {"protocol": self.state, "rng": self.rng.bit_generator.state,
                "writers": {w.name: w.resume_state() for w in self.writers}}
        checkpoint.write(self.rundir.checkpoints, engine.snapshot(), meta, engine.step,
                         engine.time)
        self.last_step = engine.step
        self.last_time = time.monotonic()
        self.rundir.log(f"checkpoint at t = {engine.time:.6g} s (step {engine.step})")

    def between(self, engine):
        if self.bar is not None:
            self.bar.update(engine)
        if self.signals.received is not None:
            self.write_checkpoint()
            return True
        if engine.step - self.last_step >= self.every_steps \
                or time.monotonic() - self.last_time >= self.every_seconds:
            self.write_checkpoint()
        return False

    def drive(self):
        """Run the protocol's remaining phases; returns the results dict."""
        engine, protocol = self.engine, self.protocol
        wall = time.perf_counter()
        cpu = time.process_time()
        start_step = engine.step
        with _Signals() as self.signals, progress_bar(self.show) as bars:
            if engine.time == 0 and self.state["phase"] == 0 and not self.state["states"]:
                self.write_all(engine)
                self.write_checkpoint()
            while self.state["phase"] < len(protocol.phases):
                phase = protocol.phases[self.state["phase"]]
                progress = self.state["states"].setdefault(phase.name, {})
                self.rundir.log(f"phase {phase.name} from t = {engine.time:.6g} s")
                self.bar = bars.phase(phase.name, engine, phase.duration())
                status = phase.run(engine, progress, every=self.every,
                                   between=self.between)
                if status == "stopped":
                    self.rundir.log(f"stopped by signal {self.signals.received}")
                    raise RunInterrupted(self.signals.received, self.rundir.path,
                                         engine.time)
                self.state["phase"] += 1
                self.rundir.log(f"phase {phase.name} ended at t = {engine.time:.6g} s "
                                f"(step {engine.step})")
                verdict = phase.verdict(progress)
                if verdict:
                    self.rundir.log(f"phase {phase.name}: {verdict}")
                self.write_checkpoint()
        self.write_all(engine)
        seconds = time.perf_counter() - wall
        cpu = time.process_time() - cpu
        results = protocol.results(engine, self.state["states"])
        results.update({"dt_s": getattr(engine, "dt", None), "steps_this_session": engine.step - start_step,
                        "wall_time_this_session_s": seconds,
                        # every thread of the process: on a shared machine the
                        # time the run would take alone on its cores
                        "cpu_time_this_session_s": cpu,
                        "particle_steps_per_s": engine.state.n * (engine.step - start_step)
                        / max(seconds, 1e-9), "threads": numba.get_num_threads()})
        self.rundir.write_results(results)
        protocol.tables(self.rundir, results)
        if self.figures:
            draw(self.rundir, protocol, results)
        self.rundir.log("finished")
        return results


# runs of a gpu.batch.Batch draw from several threads: their figures share no pyplot
# state (graindyn.figures), and this lock keeps matplotlib's caches to one at a time
_DRAWING = threading.Lock()


def draw(rundir, protocol, results=None):
    """(Re)draw the figures of a run from its files; returns their paths."""
    results = results if results is not None else rundir.results()
    with _DRAWING:
        return protocol.figures(rundir, Series(rundir.path / "series.csv").read(), results)


def _threads(requested, grains):
    """Set numba's thread count for ``grains`` grains (``requested``, or automatic when
    0 or None: _threads.use); returns (threads, the sentence that says why)."""
    try:
        return threading_policy.use(requested or 0, grains)
    except ValueError as err:
        raise ConfigError(str(err)) from None


def _stepping(engine, report):
    """How the engine advances time, for the log: its time step against the criterion of
    the time-step ``report`` (None: the step alone), or that it has none."""
    dt = getattr(engine, "dt", None)
    if dt is None:
        return "no time step (event-driven)"
    if report is None or not report.get("critical_time_s"):
        return f"dt = {dt:.4g} s"
    return (f"dt = {dt:.4g} s ({dt / report['critical_time_s']:.3f} of the "
            f"{report['criterion']})")


def _threading_line(threads, why):
    notice = f"; {threading_policy.NOTICE}" if threading_policy.NOTICE else ""
    return f"{threads} threads ({why}), threading layer {threading_policy.layer()}{notice}"


def execute(config: Config, out, show_progress=True, echo=print):
    """Start the run of ``config`` in the new run directory ``out``; returns its results."""
    report = check(config)
    threads, why = _threads(config.run.threads, config.grains.count)
    protocol = build.protocol(config)
    rng = np.random.default_rng(config.run.seed)
    state = build.sample(config, protocol, rng)
    engine = build.engine(config, state, protocol)
    resolved = config.model_copy(deep=True)
    for field in ("dt", "skin"):            # the engine's choices, written down
        if field in type(resolved.engine).model_fields:
            setattr(resolved.engine, field, getattr(engine, field))
    rundir = RunDirectory.create(out, dumps(resolved), {
        "seed": config.run.seed, "threads": threads, "threads_chosen": why,
        "threading_layer": threading_policy.layer(), "backend": config.run.backend,
        "engine": config.engine.kind, "grains": engine.state.n})
    rundir.log(f"start: {engine.state.n} grains, {config.engine.kind} engine, "
               f"{_stepping(engine, report)}, " + _threading_line(threads, why))
    echo(f"run directory {rundir.path}: {engine.state.n} grains, "
         f"{_stepping(engine, None)}, " + _threading_line(threads, why))
    try:
        return _Driver(rundir, protocol, engine, rng, {"phase": 0, "states": {}},
                       config.output, show_progress).drive()
    finally:
        rundir.close()


def restored(rundir, config, warn=print):
    """The protocol and the engine of the run in ``rundir`` (a RunDirectory) with
    ``config``, at its last good checkpoint: (protocol, engine, checkpoint meta, step,
    time [s]).  CheckpointError when no checkpoint fits."""
    arrays, meta, step, t = checkpoint.latest(rundir.checkpoints, warn=warn)
    protocol = build.protocol(config)
    materials = arrays["grains/materials"]
    density = np.array([m.density for m in config.materials])[materials]
    state = State.create(arrays["grains/positions"], arrays["grains/radii"], density,
                         dim=config.run.dim, materials=materials)
    engine = build.engine(config, state, protocol)
    try:
        engine.restore(arrays)
    except ValueError as err:
        raise checkpoint.CheckpointError(f"{rundir.path}: the checkpoint does not fit this "
                                         f"run's config: {err}") from None
    return protocol, engine, meta, step, t


class RunRecord:
    """A run directory read back for analysis: ``config`` (the resolved Config), ``meta``
    (version, commit, seed, machine, threads), ``results`` (results.json; None while the
    run has not finished), ``series`` ({column with its unit: array}, series.csv), and
    ``engine()``, the run's engine as its last good checkpoint left it (grains, walls,
    contacts with their history; ``engine().contacts()`` and ``engine().state`` to
    analyse, ``engine().run(...)`` to compute on from there)."""

    def __init__(self, path):
        self.path = pathlib.Path(path)
        if not (self.path / "config.toml").is_file():
            raise FileNotFoundError(f"{self.path}: not a run directory (no config.toml)")
        self.config = load(self.path / "config.toml")
        self.meta = json.loads((self.path / "meta.json").read_text())
        results = self.path / "results.json"
        self.results = json.loads(results.read_text()) if results.is_file() else None
        table = self.path / "series.csv"
        self.series = Series(table).read() if table.is_file() else {}

    def engine(self, warn=print):
        """The engine at the run's last good checkpoint (CheckpointError if none)."""
        rundir = RunDirectory(self.path)
        try:
            return restored(rundir, self.config, warn=warn)[1]
        finally:
            rundir.close()


def resume(out, show_progress=True, echo=print, threads=None, backend=None):
    """Continue the run in ``out`` from its last good checkpoint, on ``backend`` (cpu or
    gpu; default: the run's own); returns its results.  A run that finished (every phase
    done, results.json written) is left as it is and its results returned."""
    rundir = RunDirectory(out)
    config = load(rundir.path / "config.toml")
    if backend is not None and backend != config.run.backend:
        config.run.backend = backend
        check(config)
    started = rundir.meta()
    threads, why = _threads(threads or started.get("threads"),
                            started.get("grains", config.grains.count))
    protocol, engine, meta, step, t = restored(rundir, config, warn=echo)
    if meta["protocol"]["phase"] >= len(protocol.phases) \
            and (rundir.path / "results.json").is_file():
        try:
            echo(f"{rundir.path} finished at t = {t:.6g} s (step {step}): nothing to "
                 "resume, its files are left as they are (graindyn plot redraws its "
                 "figures)")
            return rundir.results()
        finally:
            rundir.close()
    rng = np.random.default_rng()
    rng.bit_generator.state = meta["rng"]
    rundir.log(f"resume from t = {t:.6g} s (step {step}), {_threading_line(threads, why)}, "
               f"backend {config.run.backend}")
    echo(f"resuming {rundir.path} at t = {t:.6g} s (step {step}), "
         + _threading_line(threads, why))
    try:
        driver = _Driver(rundir, protocol, engine, rng, meta["protocol"], config.output,
                         show_progress)
        driver.resume(meta, t)
        return driver.drive()
    finally:
        rundir.close()
