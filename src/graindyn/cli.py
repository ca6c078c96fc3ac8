"""The graindyn command line: run, validate, info, plot, sweep, study.

Exit codes: 0 success; 1 the simulation broke down (NaN, blow-up); 2 a bad config,
run directory or checkpoint (one message, no traceback); 130/143 interrupted by
SIGINT/SIGTERM after writing a checkpoint.
"""
import pathlib
import sys
from typing import Annotated, Optional

import typer

from . import __version__

app = typer.Typer(add_completion=False, no_args_is_help=True,
                  help="graindyn: granular dynamics simulator and virtual soil laboratory.")


def _fail(message, code=2):
    typer.echo(f"error: {message}", err=True)
    raise typer.Exit(code)


def _run_directory(path):
    """``path`` if it holds a run (its config.toml); otherwise a clear failure, naming a
    sweep's folder or a study's for what it is."""
    if not path.is_dir():
        _fail(f"{path}: no such run directory")
    if not (path / "config.toml").is_file():
        if (path / "points.json").is_file() or (path / "summary.csv").is_file():
            _fail(f"{path}: a sweep's or a study's folder, not a run directory: its runs "
                  "are the folders below it (graindyn sweep SWEEP.toml --summarize "
                  "redraws a sweep's tables and figures)")
        _fail(f"{path}: not a run directory (no config.toml)")
    return path


@app.command()
def run(
    config: Annotated[Optional[pathlib.Path], typer.Argument(
        help="TOML config of the run (see examples/*.toml).")] = None,
    out: Annotated[Optional[pathlib.Path], typer.Option(
        "--out", "-o", help="Run directory to create [default: runs/<run.name>].")] = None,
    threads: Annotated[Optional[int], typer.Option(
        help="CPU threads (overrides run.threads; 0 = automatic: one below the threading layer's crossover, all cores above; see graindyn info).", min=0)] = None,
    backend: Annotated[Optional[str], typer.Option(
        help="Compute backend, cpu or gpu (overrides run.backend; gpu needs the gpu "
             "extra and an NVIDIA GPU, see docs/gpu_notes.md).")] = None,
    resume: Annotated[Optional[pathlib.Path], typer.Option(
        help="Continue the run in this run directory from its last checkpoint.")] = None,
    progress: Annotated[bool, typer.Option(
        help="Show a progress bar (only on a terminal).")] = True,
):
    """Run a config into a run directory, or --resume an interrupted run.

    The run directory gets the resolved config, meta data (version, commit, seed,
    machine, threads), run.log, series.csv, results.json, figures/, vtk/ and
    checkpoints/.  SIGINT or SIGTERM writes a checkpoint and stops (exit 130/143).
    """
    from .config import ConfigError, load
    from .engines.soft.simulation import SimulationError
    from .output.checkpoint import CheckpointError
    from .runner import RunInterrupted, execute
    from .runner import resume as resume_run

    if (config is None) == (resume is None):
        _fail("give either CONFIG or --resume RUNDIR (not both)")
    try:
        if backend not in (None, "cpu", "gpu"):
            _fail(f"--backend = {backend!r}: choose cpu or gpu")
        if resume is not None:
            results = resume_run(_run_directory(resume), show_progress=progress,
                                 echo=typer.echo, threads=threads, backend=backend)
        else:
            cfg = load(config)
            if threads is not None:
                cfg.run.threads = threads
            if backend is not None:
                cfg.run.backend = backend
            results = execute(cfg, out or pathlib.Path("runs") / cfg.run.name,
                              show_progress=progress, echo=typer.echo)
    except (ConfigError, CheckpointError, FileExistsError, FileNotFoundError) as err:
        _fail(err)
    except SimulationError as err:
        _fail(err, 1)
    except RunInterrupted as err:
        _fail(err, 128 + err.signum)
    summary = {k: v for k, v in results.items() if isinstance(v, (int, float, bool))}
    typer.echo("\n".join(f"  {k}: {v:.6g}" if isinstance(v, float) else f"  {k}: {v}"
                         for k, v in summary.items()))


@app.command()
def validate(config: Annotated[pathlib.Path, typer.Argument(
        help="TOML config, or sweep file (one with a base = ...), to check.")]):
    """Check a config without simulating: exit 0 when it can run, 2 otherwise.  A sweep
    file (docs/sweeps.md) is checked as ``graindyn sweep --dry-run`` checks it: its base
    config and every point's config."""
    from .config import ConfigError, load
    from .config.load import read_toml
    from .engines import ENGINES
    from .runner import check
    from .sweep import Sweep

    try:
        if "base" in read_toml(config):
            plan = Sweep.load(config)
            typer.echo(f"{config}: ok, a sweep of {len(plan.points)} points, "
                       f"{len(plan.runs)} runs, on {plan.base_path}\n  graindyn sweep "
                       f"{config} --dry-run lists them")
            return
        cfg = load(config)
        report = check(cfg)
    except ConfigError as err:
        _fail(err)
    c = cfg.contact
    laws = (f"contact: {c.normal} + {c.damping} + {c.tangential} + rolling {c.rolling} + "
            f"twisting {c.twisting}") if ENGINES[cfg.engine.kind].contact_laws else \
        "contact: the materials' restitution and friction (rigid grains, no [contact] laws)"
    if report["critical_time_s"] is None:
        stepping = f"engine {cfg.engine.kind}: {report['criterion']}"
    else:
        dt = getattr(cfg.engine, "dt", None)
        stepping = (f"{report['criterion']} {report['critical_time_s']:.4g} s, suggested dt "
                    f"{report['suggested_dt_s']:.4g} s"
                    + (f", dt {dt:.4g} s = {report['fraction']:.3f} of it" if dt else ""))
    typer.echo(f"{config}: ok\n  {cfg.grains.count} grains in {cfg.run.dim}D, protocol "
               f"{cfg.protocol.kind}\n  {laws}\n  {stepping}")


@app.command()
def info():
    """Version, backends found (CPU threads, GPU), compile cache, laws and integrators."""
    import warnings

    import numba
    import numpy as np

    from . import _jit, _threads
    from .engines import ENGINES
    from .engines.soft.gpu import unavailable
    from .engines.soft.integrators import NAMES
    from .physics import registry
    from .protocols import PROTOCOLS

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        gpu = unavailable()
        if gpu is None:
            from numba import cuda
            names = [getattr(d, "name", "CUDA simulator") for d in cuda.list_devices()]
            gpu = "backend gpu available: " + ", ".join(
                n.decode() if isinstance(n, bytes) else str(n) for n in names)
        else:
            gpu = f"none: {gpu}"
    cache = _jit.CACHE_DIR
    size = sum(p.stat().st_size for p in cache.rglob("*") if p.is_file()) \
        if cache.exists() else 0
    lines = [f"graindyn {__version__}",
             f"python {sys.version.split()[0]}, numpy {np.__version__}, numba {numba.__version__}",
             f"cpu: {numba.config.NUMBA_NUM_THREADS} threads, threading layer "
             f"{_threads.layer()}" + (f" ({_threads.NOTICE})" if _threads.NOTICE else "")
             + f"; run.threads = 0: {_threads.rule()}",
             f"gpu: {gpu}",
             f"compile cache: {cache} ({size / 1e6:.1f} MB"
             + (")" if cache.exists() else ", empty: the first run compiles, ~1-2 min)")]
    lines.append("engines (engine.kind):")
    lines += [f"  {kind}: {entry.summary}" for kind, entry in ENGINES.items()]
    lines.append("protocols (protocol.kind):")
    lines += [f"  {kind}: {protocol.summary}" for kind, protocol in PROTOCOLS.items()]
    for mode in registry.MODES:
        lines.append(f"{mode} laws: " + ", ".join(law.name for law in registry.laws(mode)))
    lines.append("integrators (soft engine): " + ", ".join(NAMES))
    typer.echo("\n".join(lines))


@app.command()
def plot(rundir: Annotated[pathlib.Path, typer.Argument(help="A finished run directory.")]):
    """Redraw the figures of a finished run from its saved files."""
    from .config import ConfigError, build, load
    from .output.rundir import RunDirectory
    from .runner import draw

    try:
        cfg = load(_run_directory(rundir) / "config.toml")
        paths = draw(RunDirectory(rundir), build.protocol(cfg))
    except (ConfigError, FileNotFoundError) as err:
        _fail(err)
    typer.echo("\n".join(str(p) for p in paths))


@app.command("sweep")
def sweep_command(
    sweep_file: Annotated[pathlib.Path, typer.Argument(
        help="TOML sweep file: base config, seeds, [[vary]] (see docs/sweeps.md).")],
    out: Annotated[Optional[pathlib.Path], typer.Option(
        "--out", "-o", help="Sweep directory [default: runs/<sweep file name>].")] = None,
    scheduler: Annotated[Optional[str], typer.Option(
        help="Address of a running Dask scheduler (tcp://host:8786) instead of a local "
        "cluster; its workers need graindyn and a shared file system.")] = None,
    workers: Annotated[Optional[int], typer.Option(
        help="Worker processes of the local cluster [default: cores / threads].",
        min=1)] = None,
    threads_per_worker: Annotated[int, typer.Option(
        help="numba threads of each run (each worker runs one point at a time).",
        min=1)] = 1,
    keep: Annotated[Optional[pathlib.Path], typer.Option(
        help="Keep folder: the record of each finished run (config.toml, meta.json, "
        "results.json), the sweep's files and summaries are copied there, and the runs "
        "recorded there count as finished (a folder to commit, or to carry to another "
        "machine).")] = None,
    dry_run: Annotated[bool, typer.Option(
        "--dry-run", help="Check the sweep and list its points, run nothing.")] = False,
    summarize: Annotated[bool, typer.Option(
        "--summarize", help="Write the summaries of the runs finished so far (with "
        "--keep: those recorded there too), run nothing.")] = False,
    status: Annotated[bool, typer.Option(
        "--status", help="Show where each run stands, run nothing: finished (with "
        "--keep: those recorded there too), started (the simulated time reached, its "
        "rate and its last phase or level; running, or interrupted and resumable), "
        "failed or not started.")] = False,
    seeds: Annotated[Optional[str], typer.Option(
        help="Run only these seeds of the sweep (comma-separated, e.g. 3,4,5); the "
        "summary covers every finished run.")] = None,
    points: Annotated[Optional[str], typer.Option(
        help="Run only these points (their run folders, comma-separated, as --dry-run "
        "lists them: reference,youngs_modulus=1e9).")] = None,
):
    """Run a parameter sweep on Dask: every point (parameter, value, seed) in its own
    run directory, then summary.csv, summary.json and the protocol's tables and figures.
    Runs with backend gpu (and no --scheduler) run in this process as one GPU ensemble.

    Rerunning the same command skips finished points, resumes interrupted ones and
    retries failed ones; --seeds and --points run a part of the sweep first, into the
    same directory.  Exit codes: 0 all points (those selected) finished, 1 some failed
    (listed), 2 a bad sweep file or config, 130 interrupted.
    """
    from .config import ConfigError
    from .sweep import Sweep, SweepInterrupted, run as run_sweep, summarize as summarize_sweep
    from .sweep import standing, value_text

    if scheduler is not None and workers is not None:
        _fail("--workers sets the size of the local cluster: leave it out with --scheduler")
    chosen = None
    if seeds is not None:
        try:
            chosen = {int(v) for v in seeds.split(",") if v.strip()}
        except ValueError:
            chosen = set()
        if not chosen:
            _fail(f"--seeds = {seeds!r}: give integers separated by commas")
    names = None if points is None else {v.strip() for v in points.split(",") if v.strip()}
    try:
        plan = Sweep.load(sweep_file)
        target = out or pathlib.Path("runs") / sweep_file.stem
        if dry_run:
            listed = {p.name for p in plan.selected(chosen, names)}
            runs = {p.name for p in plan.runs}
            gpu = {p.name for p in plan.runs if p.config.run.backend == "gpu"}
            typer.echo(f"{sweep_file}: ok, {len(plan.points)} points, {len(runs)} runs "
                       f"into {target}" + (f"; {len(gpu)} with backend gpu would run as one "
                                           "GPU ensemble" if gpu and scheduler is None
                                           else ""))
            for p in (p for p in plan.points if p.name in listed):
                what = "reference" if p.parameter is None else \
                    f"{p.parameter} = {value_text(p.value)}"
                typer.echo(f"  {p.name:40s} {what}, seed {p.seed}"
                           + (" (the reference run)" if p.parameter and p.is_reference
                              else ""))
            return
        if summarize:
            summarize_sweep(plan, target, keep=keep)
            return
        if status:
            for line in _standing_lines(standing(plan, target, keep=keep), target):
                typer.echo(line)
            return
        report = run_sweep(plan, target, scheduler=scheduler, workers=workers,
                           threads_per_worker=threads_per_worker, keep=keep,
                           seeds=chosen, points=names)
    except (ConfigError, FileExistsError) as err:
        _fail(err)
    except SweepInterrupted as err:
        _fail(err, 130)
    except KeyboardInterrupt:
        _fail("interrupted: rerun the same command to continue", 130)
    if report.exit_code:
        raise typer.Exit(report.exit_code)


def _duration(seconds):
    """A duration for people: 45 s, 12 min, 3.2 h."""
    if seconds < 120:
        return f"{seconds:.0f} s"
    return f"{seconds / 60:.0f} min" if seconds < 7200 else f"{seconds / 3600:.1f} h"


def _standing_lines(rows, out):
    """What ``--status`` prints (``graindyn sweep``: sweep.standing; ``graindyn study
    settlement``: studies.settlement.study_standing): a line per run, then the count of
    each state."""
    lines, counts = [], {}
    for row in rows:
        state = row["state"]
        counts[state] = counts.get(state, 0) + 1
        if state == "finished":
            text = "finished" + (" (recorded in the keep folder)" if row.get("kept") else "")
            if row.get("wall_s") is not None:
                text += f", last session {_duration(row['wall_s'])} of wall time"
        elif state == "failed":
            text = f"FAILED: {row['error']}"
        elif state == "started":
            text = "started"
            if row["simulated_s"] is not None:
                text += f": t = {row['simulated_s']:.4g} s"
            if row["rate"] is not None:
                text += f" ({row['rate']:.3g} simulated s per wall hour)"
            text += f", logged {_duration(row['quiet_s'])} ago: {row['news']}"
        else:
            text = state
        lines.append(f"  {row['name']:40s} {text}")
    order = ("finished", "started", "failed", "not started")
    lines.append(f"{out}: {len(rows)} runs, " + ", ".join(
        f"{counts[s]} {s}" for s in order if counts.get(s)))
    return lines


cache = typer.Typer(invoke_without_command=True,
                    help="The compile cache: where it is and how big (clear: remove old "
                    "folders).")
app.add_typer(cache, name="cache")


@cache.callback()
def cache_show(context: typer.Context):
    """Each compile-cache folder, its size, and which one this source tree uses."""
    if context.invoked_subcommand is not None:
        return
    from . import _jit

    folders = _jit.cache_folders()
    typer.echo(f"compile cache root: {_jit.CACHE_ROOT} (GRAINDYN_CACHE_DIR moves it)")
    for path, size, current in folders:
        typer.echo(f"  {path.name}  {size / 1e6:8.1f} MB" + ("  (in use)" if current else ""))
    if not any(current for *_, current in folders):
        typer.echo(f"  {_jit.CACHE_DIR.name}  (in use, empty: the next run compiles)")
    typer.echo(f"total {sum(size for _, size, _ in folders) / 1e6:.1f} MB")


@cache.command("clear")
def cache_clear(everything: Annotated[bool, typer.Option(
        "--all", help="Also the folder in use (the next run compiles again, ~1-2 min).")]
        = False):
    """Remove the compile-cache folders that this source tree no longer uses."""
    from . import _jit

    removed = _jit.clear_cache(everything)
    typer.echo(f"removed {len(removed)} folder(s), "
               f"{sum(size for _, size in removed) / 1e6:.1f} MB")


study = typer.Typer(no_args_is_help=True, help="Studies that reproduce the documents' "
                    "comparisons.")
app.add_typer(study, name="study")


@study.command("integrators")
def study_integrators(
    out: Annotated[pathlib.Path, typer.Option(
        "--out", "-o", help="Folder for the figures and tables.")] = pathlib.Path(
            "runs/study_integrators"),
    quick: Annotated[bool, typer.Option(help="Fewer and shorter runs (about a minute).")]
    = False,
):
    """Oquendo Fig. 2 (energy spread vs dt), Perez Fig. 3 (collision velocity error), the
    order-of-accuracy table of every integrator and the symmetric top (VALIDATION G2),
    as PNG, CSV and summary.json."""
    from .studies.integrators import run_integrator_study

    summary = run_integrator_study(out, quick=quick)
    typer.echo(f"study written to {out} ({len(summary) - 1} parts: "
               + ", ".join(k for k in summary if k != "quick") + ")")


def _numbers(text, what):
    try:
        values = tuple(int(v) for v in text.split(",") if v.strip())
    except ValueError:
        values = ()
    if not values or min(values) < 1:
        _fail(f"{what} = {text!r}: give positive integers separated by commas")
    return values


@study.command("settlement")
def study_settlement(
    out: Annotated[pathlib.Path, typer.Option(
        "--out", "-o", help="Folder of the study (bed, run directories, tables, figures); "
        "rerunning reuses the bed and the finished runs.")] = pathlib.Path(
            "runs/study_settlement"),
    config: Annotated[Optional[pathlib.Path], typer.Option(
        "--config", help="Base TOML config, protocol.kind = 'cyclic' [default: Karrech "
        "Table 1, as examples/cyclic.toml].")] = None,
    grains: Annotated[Optional[int], typer.Option(
        help="Grain count; a cylinder's radius is scaled to keep the bed's depth "
        "[default: 430, radius 24.9 mm; --quick 120].", min=1)] = None,
    cycles: Annotated[Optional[int], typer.Option(
        help="Load cycles N of every run [default: 100; --quick 8].", min=2)] = None,
    initial_cycles: Annotated[Optional[int], typer.Option(
        "--initial-cycles", help="k_i [default: 10; --quick 2].", min=1)] = None,
    k: Annotated[Optional[str], typer.Option(
        "--k", help="Computed cycles k of the k family, comma-separated, at h = "
        "--h-fixed [default: 10,20,40].")] = None,
    h: Annotated[Optional[str], typer.Option(
        "--h", help="Extrapolated cycles h of the h family, at k = --k-fixed "
        "[default: 10,20,40].")] = None,
    k_fixed: Annotated[Optional[int], typer.Option(
        "--k-fixed", help="k of the h family [default: 40].", min=2)] = None,
    h_fixed: Annotated[Optional[int], typer.Option(
        "--h-fixed", help="h of the k family [default: 10].", min=1)] = None,
    estimator: Annotated[str, typer.Option(help="linear (Eq. 16), shenton (Eq. 17-21) or logarithmic (c + a ln t).")]
    = "shenton",
    mode: Annotated[str, typer.Option(
        help="Loading mode: fully (confined, the base's load) or partially "
        "(protocol.plate_fraction = 0.8, 5.87 kPa at 10 Hz, Karrech Sec. 6).")] = "fully",
    set_: Annotated[Optional[list[str]], typer.Option(
        "--set", help="KEY=VALUE put on the config after the mode, KEY dotted "
        "(protocol.plate_fraction=0.8), VALUE read as TOML; repeatable.")] = None,
    threads: Annotated[Optional[int], typer.Option(
        help="numba threads of each run [default: the automatic count].", min=1)] = None,
    jobs: Annotated[int, typer.Option(
        help="Runs at a time, each in its own process (one per free core).", min=1)] = 1,
    replicas: Annotated[int, typer.Option(
        help="Full DEM runs of the bed with one grain moved by 1, 2, ... nm: how far "
        "apart two computations of the same bed land (the floor of every error).",
        min=0)] = 0,
    procedure_replicas: Annotated[int, typer.Option(
        "--procedure-replicas", help="Each procedure run repeated from the beds of the "
        "first of these replicas and compared with full DEM of its own bed: the mean "
        "error over the beds with its standard error (at most --replicas).", min=0)] = 0,
    keep: Annotated[Optional[pathlib.Path], typer.Option(
        help="A folder, small enough to commit, that keeps the bed, each finished run's "
        "record and the tables and figures: a study with another --out takes the bed and "
        "the finished runs from it, so that its replicas grow over sessions.")] = None,
    quick: Annotated[bool, typer.Option(
        help="A 120-grain soft bed, 8 cycles, k_i = 2, k and h in 2, 3 (about a minute).")]
    = False,
    status: Annotated[bool, typer.Option(
        "--status", help="Show where the bed and each run of this study stand (finished, "
        "with --keep those kept there too; started: the simulated time reached, its rate "
        "and last line; not started), run nothing.")] = False,
):
    """Karrech Fig. 11-13: one bed settled once; from it full DEM and the sequential
    procedure for several k and h; their settlement paths, the errors in settlement,
    coordination and configuration (Eq. 22) at the last cycle, and the gained time
    (t_full - t_procedure) / t_procedure, as summary.csv, paths.csv, summary.json and
    PNG figures (docs/settlement.md).  Run again with the same --out (or the same
    --keep), it reuses the bed and the finished runs and resumes a run stopped by SIGINT
    or SIGTERM (exit 130/143) from its checkpoint."""
    import signal
    import tomllib

    from .config import ConfigError
    from .config.load import read_toml
    from .runner import RunInterrupted
    from .studies.settlement import run_settlement_study, study_standing

    overrides = {}
    for item in set_ or []:
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            _fail(f"--set {item!r}: give KEY=VALUE")
        try:
            overrides[key.strip()] = tomllib.loads(f"v = {text.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            overrides[key.strip()] = text.strip()
    try:
        base = read_toml(config) if config is not None else None
        arguments = dict(quick=quick, base=base, grains=grains, cycles=cycles,
                         initial_cycles=initial_cycles, ks=k and _numbers(k, "--k"),
                         hs=h and _numbers(h, "--h"), k_fixed=k_fixed, h_fixed=h_fixed,
                         estimator=estimator, mode=mode, overrides=overrides,
                         replicas=replicas, procedure_replicas=procedure_replicas)
        if status:
            for line in _standing_lines(study_standing(out, keep=keep, **arguments), out):
                typer.echo(line)
            return
        summary = run_settlement_study(out, threads=threads, jobs=jobs, keep=keep,
                                       echo=typer.echo, **arguments)
    except (ConfigError, ValueError, FileExistsError) as err:
        _fail(err)
    except RunInterrupted as err:
        _fail(f"study interrupted by {signal.Signals(err.signum).name}, the running run's "
              "checkpoint written: the same command resumes it", 128 + err.signum)
    for name, r in summary["runs"].items():
        typer.echo(f"  {name}: settlement {1e3 * r['settlement_m']:.4g} mm, error "
                   f"{100 * r['settlement_error']:.3g} %, coordination error "
                   f"{100 * r['coordination_error']:.3g} %, E_r "
                   f"{r['configuration_error']:.3g}, gained time "
                   f"{r['gained_time_percent']:.3g} %")
    if summary["forecast"]:
        typer.echo("  full DEM forecast from its own past (rms relative error): " + ", ".join(
            f"{key.replace('_', ' ')} {100 * f['rms']:.2g} %"
            for key, f in summary["forecast"].items()))
    typer.echo(f"study written to {out}")


@study.command("settlement-beds")
def study_settlement_beds(
    folders: Annotated[list[pathlib.Path], typer.Argument(
        help="Folders of finished settlement studies of other beds (--set run.seed=N), "
        "run with the same procedure settings.")],
    out: Annotated[pathlib.Path, typer.Option(
        "--out", "-o", help="Folder for pooled.json, pooled.csv and "
        "settlement_ensemble.png.")] = pathlib.Path("runs/settlement_beds"),
    run: Annotated[Optional[str], typer.Option(
        help="The procedure run to pool [default: the one every study has].")] = None,
    at: Annotated[Optional[str], typer.Option(
        help="Cycles at which to report the bias, comma-separated [default: five "
        "evenly spaced].")] = None,
):
    """The procedure over several beds: every (procedure, full DEM of the same bed) pair
    of every study, the procedure's replicas included, pooled into one ensemble, its
    bias mean(s_p - s_full) / mean(s_full) with its standard error along the cycles
    (docs/settlement.md).  Reads the studies' summary.json; runs nothing."""
    from .studies.settlement_beds import pool_beds

    try:
        pooled = pool_beds(folders, out, run=run, at=at and _numbers(at, "--at"))
    except ValueError as err:
        _fail(err)
    e = pooled["ensemble"]
    typer.echo(f"{pooled['run']}: {len(e['pairs'])} pairs from {len(folders)} studies, "
               f"speed-up {e['speedup']:.2f} (summed CPU), full DEM's spread "
               f"{100 * e['full_spread']:.2g} %")
    for cycle, (bias, se) in e["bias_at"].items():
        typer.echo(f"  cycle {cycle}: bias {100 * bias:+.2f} +- {100 * se:.2f} %")
    after = [f"{lag}: {s / f:.2f}" for lag, (s, f, n) in
             e["settlement_after_jumps"].items() if n and f]
    if after:
        typer.echo("  settlement of the computed cycles over full DEM's at the same "
                   "cycles, by cycles since the last jump: " + ", ".join(after))
    typer.echo(f"pooled into {out}")


def main():
    """Console entry point."""
    app()
