"""Running a config: a run directory in, results out, nothing lost on interruption.

``execute(config, out)`` starts a run, ``resume(out)`` continues one from its last
checkpoint.  Between compiled chunks the driver records the time series, writes VTK
snapshots, shows progress and writes checkpoints (every ``checkpoint_every_steps`` steps
or ``checkpoint_every_seconds`` of wall-clock time, at each phase end, and on SIGINT or
SIGTERM, after which it raises RunInterrupted).  Chunks end on the same steps whether
or not the run is cut, so a resumed run gives the same numbers to the last bit as an
uninterrupted one (same backend and thread count).
"""
import math
import signal
import threading
import time

import numba
import numpy as np

from . import _threads as threading_policy

from .analysis.energy import energy_budget
from .analysis.packing import coordination_number
from .config import ConfigError, build, dumps, load
from .config.models import Config
from .core.state import State
from .core.triggers import Periodic
from .output import checkpoint
from .output.progress import progress_bar
from .output.rundir import RunDirectory, Series
from .output.vtk import VtkSeries
from .protocols.deposition import Deposition
from .protocols.oedometer import Oedometer

PROTOCOLS = {"deposition": Deposition, "oedometer": Oedometer}


class RunInterrupted(RuntimeError):
    """A run stopped by a signal after writing its checkpoint."""

    def __init__(self, signum, rundir, step):
        self.signum = signum
        super().__init__(f"interrupted by {signal.Signals(signum).name} at step {step}; "
                         f"checkpoint written: resume with 'graindyn run --resume {rundir}'")


def check(config: Config):
    """Everything about a config that can be checked without simulating: the contact
    model against the materials, the time step, the backend.  ConfigError otherwise;
    returns the time-step report."""
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


def series_row(sim):
    """One row of the standard time series (column names carry the units)."""
    e = energy_budget(sim)
    speed = np.sqrt(np.max(np.einsum("ij,ij->i", sim.state.velocities,
                                     sim.state.velocities), initial=0.0))
    row = {"time [s]": sim.time, "step [-]": sim.step, "kinetic [J]": e["kinetic"],
           "rotational [J]": e["rotational"], "gravitational [J]": e["gravitational"],
           "elastic [J]": e["elastic"], "dissipated_normal [J]": e["dissipated_normal"],
           "dissipated_tangential [J]": e["dissipated_tangential"],
           "wall_work [J]": e["wall_work"], "max_speed [m/s]": speed,
           "coordination [-]": coordination_number(sim)}
    for k, wall in enumerate(sim.walls.walls):
        row[f"force_{wall.name} [N]"] = sim.walls.normal_force(k)
    return row


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
    """The between-chunk work of one run: series, snapshots, progress, checkpoints."""

    def __init__(self, rundir, protocol, sim, rng, progress_state, vtk_entries, show):
        self.rundir, self.protocol, self.sim, self.rng = rundir, protocol, sim, rng
        protocol.log = rundir.log
        self.state = progress_state
        out = protocol.config.output
        self.series = Series(rundir.path / "series.csv")
        self.vtk = VtkSeries(rundir.vtk, out.vtk_contacts, vtk_entries)
        self.every = [(Periodic(time=out.series_every), self.record)]
        if out.vtk_every is not None:
            self.every.append((Periodic(time=out.vtk_every), self.vtk.write))
        self.every_steps = out.checkpoint_every_steps or math.inf
        self.every_seconds = out.checkpoint_every_seconds or math.inf
        self.last_step = sim.step
        self.last_time = time.monotonic()
        self.show = show
        self.signals = None
        self.bar = None

    def record(self, sim):
        self.series.append(series_row(sim))

    def write_checkpoint(self):
        sim = self.sim
        meta = {"protocol": self.state, "vtk": self.vtk.entries,
                "rng": self.rng.bit_generator.state}
        checkpoint.write(self.rundir.checkpoints, sim.snapshot(), meta, sim.step, sim.time)
        self.last_step = sim.step
        self.last_time = time.monotonic()
        self.rundir.log(f"checkpoint at step {sim.step}, t = {sim.time:.6g} s")

    def between(self, sim):
        if self.bar is not None:
            self.bar.update(sim)
        if self.signals.received is not None:
            self.write_checkpoint()
            return True
        if sim.step - self.last_step >= self.every_steps \
                or time.monotonic() - self.last_time >= self.every_seconds:
            self.write_checkpoint()
        return False

    def drive(self):
        """Run the protocol's remaining phases; returns the results dict."""
        sim, protocol = self.sim, self.protocol
        chunk = int(min(20000, max(100, 2e6 / sim.state.n)))
        wall = time.perf_counter()
        start_step = sim.step
        with _Signals() as self.signals, progress_bar(self.show) as bars:
            if sim.step == 0 and self.state["phase"] == 0 and not self.state["states"]:
                self.record(sim)
                self.vtk.write(sim)
                self.write_checkpoint()
            while self.state["phase"] < len(protocol.phases):
                name = protocol.phases[self.state["phase"]]
                phase = self.state["states"].setdefault(name, {})
                self.rundir.log(f"phase {name} from step {sim.step}")
                self.bar = bars.phase(name, sim, protocol.phase_duration(name))
                status = protocol.run_phase(name, sim, phase, every=self.every,
                                            between=self.between, max_chunk=chunk)
                if status == "stopped":
                    self.rundir.log(f"stopped by signal {self.signals.received}")
                    raise RunInterrupted(self.signals.received, self.rundir.path, sim.step)
                self.state["phase"] += 1
                self.rundir.log(f"phase {name} ended ({status}) at step {sim.step}, "
                                f"t = {sim.time:.6g} s")
                self.write_checkpoint()
        if not self.series.path.exists() or self.series.read()["step [-]"][-1] != sim.step:
            self.record(sim)
        self.vtk.write(sim)
        seconds = time.perf_counter() - wall
        results = protocol.results(sim, self.state["states"])
        results.update({"dt_s": sim.dt, "steps_this_session": sim.step - start_step,
                        "wall_time_this_session_s": seconds,
                        "particle_steps_per_s": sim.state.n * (sim.step - start_step)
                        / max(seconds, 1e-9), "threads": numba.get_num_threads()})
        self.rundir.write_results(results)
        protocol.tables(self.rundir, results)
        if protocol.config.output.figures:
            draw(self.rundir, protocol, results)
        self.rundir.log("finished")
        return results


# matplotlib is not thread-safe; runs of a gpu.batch.Batch draw from several threads
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


def _threading_line(threads, why):
    notice = f"; {threading_policy.NOTICE}" if threading_policy.NOTICE else ""
    return f"{threads} threads ({why}), threading layer {threading_policy.layer()}{notice}"


def execute(config: Config, out, show_progress=True, echo=print):
    """Start the run of ``config`` in the new run directory ``out``; returns its results."""
    report = check(config)
    threads, why = _threads(config.run.threads, config.grains.count)
    protocol = PROTOCOLS[config.protocol.kind](config)
    rng = np.random.default_rng(config.run.seed)
    sim = protocol.create(rng)
    resolved = config.model_copy(deep=True)
    resolved.engine.dt = sim.dt
    resolved.engine.skin = sim.skin
    rundir = RunDirectory.create(out, dumps(resolved), {
        "seed": config.run.seed, "threads": threads, "threads_chosen": why,
        "threading_layer": threading_policy.layer(), "backend": config.run.backend,
        "grains": sim.state.n})
    rundir.log(f"start: {sim.state.n} grains, dt = {sim.dt:.4g} s "
               f"({sim.dt / report['critical_time_s']:.3f} of the {report['criterion']}), "
               + _threading_line(threads, why))
    echo(f"run directory {rundir.path}: {sim.state.n} grains, dt = {sim.dt:.4g} s, "
         + _threading_line(threads, why))
    try:
        return _Driver(rundir, protocol, sim, rng, {"phase": 0, "states": {}}, [],
                       show_progress).drive()
    finally:
        rundir.close()


def resume(out, show_progress=True, echo=print, threads=None, backend=None):
    """Continue the run in ``out`` from its last good checkpoint, on ``backend`` (cpu or
    gpu; default: the run's own); returns its results."""
    rundir = RunDirectory(out)
    config = load(rundir.path / "config.toml")
    if backend is not None and backend != config.run.backend:
        config.run.backend = backend
        check(config)
    started = rundir.meta()
    threads, why = _threads(threads or started.get("threads"),
                            started.get("grains", config.grains.count))
    arrays, meta, step, t = checkpoint.latest(rundir.checkpoints, warn=echo)
    protocol = PROTOCOLS[config.protocol.kind](config)
    materials = arrays["grains/materials"]
    density = np.array([m.density for m in config.materials])[materials]
    state = State.create(arrays["grains/positions"], arrays["grains/radii"], density,
                         dim=config.run.dim, materials=materials)
    sim = protocol.build(state)
    try:
        sim.restore(arrays)
    except ValueError as err:
        raise checkpoint.CheckpointError(f"{rundir.path}: the checkpoint does not fit this "
                                         f"run's config: {err}") from None
    rng = np.random.default_rng()
    rng.bit_generator.state = meta["rng"]
    Series(rundir.path / "series.csv").truncate(step)
    vtk = VtkSeries(rundir.vtk, config.output.vtk_contacts, meta["vtk"])
    vtk.truncate(step)
    rundir.log(f"resume from step {step}, t = {t:.6g} s, {_threading_line(threads, why)}, backend "
               f"{config.run.backend}")
    echo(f"resuming {rundir.path} at step {step} (t = {t:.6g} s), "
         + _threading_line(threads, why))
    try:
        return _Driver(rundir, protocol, sim, rng, meta["protocol"], vtk.entries,
                       show_progress).drive()
    finally:
        rundir.close()
