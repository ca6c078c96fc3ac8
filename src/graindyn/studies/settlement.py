"""The convergence study of the sequential settlement procedure (Karrech et al., Sec. 5.2
and 6, Fig. 11-13): one bed settled once, then from that same settled state the full
molecular dynamics of ``cycles`` load cycles and the procedure (protocols/cyclic.py,
``extrapolation``) for several k at fixed k_i and h (the "k" family, Fig. 11a) and for
several h at fixed k_i and k (the "h" family, Fig. 11b), every run compared with the
full one at the last cycle N.

Every run is an ordinary run directory of the cyclic protocol, driven by the runner:
the bed is ``runner.execute`` of the config with one cycle and no periodic checkpoints,
so that its checkpoint written at the end of the settling (``checkpoint.prev.h5``, the
last but one) is the settled state; it is kept as ``bed/settled.h5``.  Each study run
is a run directory holding that checkpoint and a config that differs from the bed's
only in ``protocol`` (cycles, extrapolation, initial_cycles, computed_cycles,
extrapolated_cycles), and ``runner.resume`` runs its cycles phase.  A second call with
the same out folder reuses the bed and every finished run (``study_run.json``); a run
stopped by SIGINT or SIGTERM (its checkpoint written) resumes from its checkpoint, its
CPU and wall times summed over its sessions (``study_partial.json``); a run whose
session ended otherwise (killed, crashed) starts again from the settled bed, since the
time it spent is unknown.

A keep folder (``keep``, ``--keep``) holds what the study needs to go on elsewhere, small
enough to commit: the bed (``BED_FILES``: its config, the settled checkpoint and the
settling's record), each finished run's record (``RUN_FILES``: study_run.json, its
config and meta data, the residual displacements of its last cycle and the overlaps of
its relaxations) and the study's tables and figures.  A study started in an empty out
folder with the same keep folder takes the bed and the finished runs from it, so that
an ensemble of beds grows over sessions and machines without computing a run twice.

Measures, run p against the full molecular dynamics f, at the last cycle N:

- settlement error  |s_p(N) - s_f(N)| / s_f(N), s the plate's descent since the cycles
  started [m];
- coordination error  |Z_p(N) - Z_f(N)| / Z_f(N), Z = 2 C / N_free the coordination
  number of the grain pairs that overlap (|r_i - r_j| < R_i + R_j) in the state at the
  end of cycle N (geometric, so that it is defined after an extrapolation as after a
  computed cycle, whose relaxed grains carry no force until the next step);
- configuration error  E_r = ||u_f - u_p|| / ||u_f|| (Karrech Eq. 22,
  analysis.settlement.relative_error), u the (N_grains, 3) residual displacements since
  the cycles started, Frobenius norm;
- path error: the largest |s_p(c) - s_f(c)| / s_f(c) over the cycles c that run p
  reports (its computed cycles and the ends of its extrapolations).

Computation time t [s]: the CPU time of the process (``time.process_time``) spent in the
run of the cycles (``runner.resume``: the cycles, their extrapolations and relaxations,
the writing of the run's files), the settling, shared by every run, left out.  With
one numba thread on an otherwise idle core it is the wall time, which is recorded too.

Gained time (Karrech Fig. 12-13, "gained calculation time", which reaches 180 %, so
that it is relative to the procedure's time):

    G = (t_full - t_procedure) / t_procedure x 100 %,

so G = 100 % when the procedure takes half the time of full DEM; the speed-up
t_full / t_procedure = 1 + G / 100.

>>> run_settlement_study(pathlib.Path("runs/settlement"), quick=True)  # doctest: +SKIP
"""
import contextlib
import copy
import csv
import json
import math
import multiprocessing
import os
import pathlib
import shutil
import signal
import threading
import time

import numpy as np

from ..analysis.settlement import LAWS, forecast_errors, relative_error

FULL = "full_dem"
# cycles ahead at which full DEM's settlement is forecast from its own past (forecast_floor)
FORECAST_HORIZONS = (50, 100)
REPLICA_TAG = "_replica_"
REPLICA = FULL + REPLICA_TAG
PARTIAL = "study_partial.json"      # the times of an interrupted study run's sessions
# how far replica r moves one grain of the settled bed: r x PERTURBATION [m], far below
# any length of the bed (round-off of the positions is about 1e-18 m)
PERTURBATION = 1e-9
# what a keep folder holds of the bed, of a finished run (plus its last residual file)
# and of the study (module docstring)
BED_FILES = ("bed.json", "settled.h5", "run/config.toml", "run/meta.json", "run/series.csv")
RUN_FILES = ("study_run.json", "config.toml", "meta.json")
STUDY_FILES = ("summary.csv", "paths.csv", "summary.json", "ensembles.csv",
               "settlement_paths.png", "settlement_errors.png", "settlement_relaxation.png",
               "settlement_ensemble.png")


def replica_name(run, r):
    """The name of replica r of study run ``run``: the same run from the bed with one
    grain moved by r x PERTURBATION (full DEM: ``full_dem_replica_r``)."""
    return f"{run}{REPLICA_TAG}{r}"


def perturbation_of(name):
    """The displacement [m] replica ``name`` gives one grain of the bed (0 for every
    other run)."""
    _, tag, r = name.rpartition(REPLICA_TAG)
    return int(r) * PERTURBATION if tag and r.isdigit() else 0.0


def reference_of(name):
    """The full DEM run that study run ``name`` is compared with: for replica r of a
    procedure run, full DEM from the same perturbed bed (replica r of full DEM); for
    every other run, full DEM of the bed itself (so the errors of the full DEM
    replicas are how far a nanometre moves full DEM)."""
    base, tag, r = name.rpartition(REPLICA_TAG)
    if tag and r.isdigit() and base != FULL:
        return replica_name(FULL, int(r))
    return FULL


def perturb(path, displacement):
    """Move the free grain nearest the centre of the grains by ``displacement`` [m]
    along x in the checkpoint file ``path`` (its contacts, velocities and integrator
    history kept): a replica of the bed that differs from it by that much.  Returns
    the grain's index."""
    import h5py

    with h5py.File(path, "r+") as f:
        positions = f["grains/positions"][...]
        free = f["grains/fixed"][...] == 0 if "grains/fixed" in f \
            else np.ones(len(positions), bool)
        distance = np.linalg.norm(positions - positions[free].mean(axis=0), axis=1)
        grain = int(np.argmin(np.where(free, distance, np.inf)))
        positions[grain, 0] += displacement
        f["grains/positions"][...] = positions
    return grain

# Karrech et al. Table 1 (examples/cyclic.toml): diorite in a steel cylinder, fully
# confined mode; ``grains`` scales the cylinder's radius to keep the bed's depth.
TABLE1 = {
    "run": {"name": "settlement_study", "seed": 1},
    "grains": {"count": 3900, "material": "diorite",
               "diameter": {"distribution": "normal", "mean": 6.4e-3, "std": 1.13e-3}},
    "materials": [
        {"name": "diorite", "density": 2710.0, "youngs_modulus": 46.9e9,
         "poisson_ratio": 0.25, "friction_sliding": 0.5, "alpha_n": 0.44, "alpha_t": 0.44},
        {"name": "steel", "density": 7800.0, "youngs_modulus": 210e9, "poisson_ratio": 0.3,
         "friction_sliding": 0.5, "alpha_n": 0.44, "alpha_t": 0.44}],
    "contact": {"normal": "hertz", "damping": "karrech", "tangential": "karrech"},
    "walls": {"material": "steel",
              "container": {"kind": "cylinder", "radius": 0.075, "height": 0.1}},
    # the spheres' angles act on nothing: not turning them saves about a tenth of a step
    "engine": {"integrator": "gear3", "orientations": False},
    "protocol": {"kind": "cyclic", "insertion": "random", "packing_fraction": 0.05,
                 "criterion": "energy_ratio", "threshold": 1e-6, "max_time": 2.0,
                 "stress_amplitude": 14.15e3, "frequency": 50.0},
    "output": {"series_every": 5e-4},
}

# The --quick bed: 120 grains of soft sand (E = 1e8 Pa, d ~ 1 mm) in a cylinder of
# radius 2.7 mm.
QUICK = {
    "run": {"name": "settlement_study_quick", "seed": 3},
    "grains": {"count": 120, "material": "sand",
               "diameter": {"min": 0.85e-3, "max": 1.15e-3}},
    "materials": [{"name": "sand", "youngs_modulus": 1e8, "poisson_ratio": 0.25,
                   "restitution": 0.5, "friction_sliding": 0.4, "tangential_damping": 1.0}],
    "contact": {"normal": "hertz", "damping": "tsuji", "tangential": "mindlin"},
    "walls": {"material": "sand",
              "container": {"kind": "cylinder", "radius": 2.7e-3, "height": 12e-3}},
    "protocol": {"kind": "cyclic", "packing_fraction": 0.05, "threshold": 1e-5,
                 "max_time": 0.3, "stress_amplitude": 2e3, "frequency": 50.0},
    "output": {"series_every": 2e-4},
}

# Loading modes (Karrech Sec. 6): protocol settings put on top of the base config.
MODES = {
    "fully": {},
    "partially": {"protocol.plate_fraction": 0.8, "protocol.stress_amplitude": 5.87e3,
                  "protocol.frequency": 10.0},
}

# The protocol settings a study run sets; the bed is the rest of the config.
RUN_KEYS = ("cycles", "extrapolation", "initial_cycles", "computed_cycles",
            "extrapolated_cycles")
# The procedure's own settings: given to the study (--set), they go to every run of the
# procedure and leave the bed, which does not read them, as it is (and reusable).
PROCEDURE_KEYS = ("relaxation", "relaxation_iterations", "relaxation_tolerance",
                  "smoothing", "smoothing_fit", "keep_contacts", "hold_frontier",
                  "extrapolated_growth", "restart_cycles", "fit_time", "final_cycles",
                  "jump_tolerance", "undone_jump", "undone_error_order", "jump_correction")


# ------------------------------------------------------------------ configs
def set_dotted(data, key, value):
    """Set ``key`` ("protocol.plate_fraction", "materials.diorite.friction_sliding") in
    the config dict ``data`` to ``value``; missing sections are created, list items are
    found by their ``name`` or index.  ValueError when the path goes through a value."""
    parts = key.split(".")
    node = data
    for k, part in enumerate(parts[:-1]):
        if isinstance(node, list):
            names = [x.get("name") if isinstance(x, dict) else None for x in node]
            if part in names:
                node = node[names.index(part)]
            elif part.isdigit() and int(part) < len(node):
                node = node[int(part)]
            else:
                raise ValueError(f"{key}: {'.'.join(parts[:k]) or 'the config'} has no "
                                 f"item {part!r}")
        elif isinstance(node, dict):
            node = node.setdefault(part, {})
        else:
            raise ValueError(f"{key}: {'.'.join(parts[:k])} is a value, not a section")
    if not isinstance(node, dict):
        raise ValueError(f"{key}: {'.'.join(parts[:-1])} is not a section")
    node[parts[-1]] = value
    return data


def study_config(base, grains=None, overrides=None):
    """The study's config dict: ``base`` (a config dict, default Table 1) with
    ``grains`` grains (a cylinder's radius scaled by sqrt(grains / base count), so that
    the bed keeps its depth) and ``overrides`` ({dotted key: value}, e.g. a loading
    mode's protocol settings) applied last.  The protocol must be cyclic."""
    data = copy.deepcopy(base if base is not None else TABLE1)
    if grains is not None:
        old = data["grains"]["count"]
        data["grains"]["count"] = int(grains)
        box = data.get("walls", {}).get("container", {})
        if box.get("kind") == "cylinder":
            box["radius"] = box["radius"] * math.sqrt(grains / old)
    for key, value in (overrides or {}).items():
        set_dotted(data, key, value)
    if data.get("protocol", {}).get("kind") != "cyclic":
        raise ValueError("the settlement study needs protocol.kind = 'cyclic'")
    for key in RUN_KEYS:
        data["protocol"].pop(key, None)
    return data


def plan(cycles, initial_cycles=10, ks=(10, 20, 40), hs=(10, 20, 40), k_fixed=40,
         h_fixed=10, estimator="shenton", replicas=0, procedure_replicas=0):
    """The study's runs: {name: protocol settings}, full DEM first, and the families
    {"k": names (k_i, k in ks, h = h_fixed), "h": names (k_i, k = k_fixed, h in hs),
    "replica": names of the ``replicas`` full DEM runs of a perturbed bed (replica r
    has one grain moved by r x PERTURBATION, perturbation_of), "procedure_replica":
    names of the replicas 1 to ``procedure_replicas`` of every procedure run, each from
    the bed of the full DEM replica it is compared with (reference_of)}; a run in both
    families is made once."""
    if estimator not in LAWS:
        raise ValueError(f"estimator {estimator!r}: choose one of {', '.join(LAWS)}")
    if replicas < 0:
        raise ValueError(f"replicas must be >= 0, got {replicas}")
    if not 0 <= procedure_replicas <= replicas:
        raise ValueError(f"procedure replicas must be between 0 and the replicas of full "
                         f"DEM ({replicas}), each being compared with full DEM of its "
                         f"own bed; got {procedure_replicas}")
    runs = {FULL: {"cycles": cycles, "extrapolation": "none"}}
    families = {"k": [], "h": [], "replica": [], "procedure_replica": []}
    for r in range(1, replicas + 1):
        name = replica_name(FULL, r)
        runs[name] = {"cycles": cycles, "extrapolation": "none"}
        families["replica"].append(name)
    for family, pairs in (("k", [(k, h_fixed) for k in ks]),
                          ("h", [(k_fixed, h) for h in hs])):
        for k, h in pairs:
            name = f"{estimator}_ki{initial_cycles}_k{k}_h{h}"
            runs.setdefault(name, {"cycles": cycles, "extrapolation": estimator,
                                   "initial_cycles": initial_cycles, "computed_cycles": k,
                                   "extrapolated_cycles": h})
            families[family].append(name)
    for name in [n for n in runs if n != FULL and n not in families["replica"]]:
        for r in range(1, procedure_replicas + 1):
            runs[replica_name(name, r)] = dict(runs[name])
            families["procedure_replica"].append(replica_name(name, r))
    return runs, families


# ------------------------------------------------------------------ the bed
def prepare_bed(data, folder, echo=print):
    """Settle the bed of config dict ``data`` once (``runner.execute`` with one cycle and
    no periodic checkpoints) in ``folder``/run; the checkpoint written at the end of the
    settling is copied to ``folder``/settled.h5.  Reused when ``folder``/bed.json holds
    the same config; ValueError when it holds another.  Returns the bed run's folder."""
    from ..config import validate
    from ..config.build import protocol as build_protocol
    from ..output import checkpoint
    from ..runner import execute

    folder = pathlib.Path(folder)
    settled, record, run = folder / "settled.h5", folder / "bed.json", folder / "run"
    if record.exists():
        if json.loads(record.read_text())["config"] != json.loads(json.dumps(data)):
            raise ValueError(f"{folder} holds a bed of another config: choose another "
                             "--out or remove it")
        if settled.exists():
            echo(f"bed: reusing {settled}")
            return run
    if run.exists():
        shutil.rmtree(run)
    folder.mkdir(parents=True, exist_ok=True)
    record.write_text(json.dumps({"config": data}, indent=1))
    bed = copy.deepcopy(data)
    bed["protocol"].update(cycles=1, extrapolation="none")
    bed.setdefault("output", {}).update(checkpoint_every_steps=None,
                                        checkpoint_every_seconds=None, figures=False)
    config = validate(bed, "settlement study bed")
    settle_end = len(build_protocol(config).phases) - 1
    wall = time.perf_counter()
    results = execute(config, run, show_progress=False, echo=echo)
    _, meta, step, t = checkpoint.read(run / "checkpoints" / checkpoint.PREVIOUS)
    if meta["protocol"]["phase"] != settle_end or "cycles" in meta["protocol"]["states"]:
        raise RuntimeError(f"{run}: the previous checkpoint is not the end of the settling")
    shutil.copy(run / "checkpoints" / checkpoint.PREVIOUS, settled)
    report = dict(results.get("deposition", {}), settle_time_s=t, settle_steps=step,
                  dt_s=results.get("dt_s"), wall_s=time.perf_counter() - wall)
    record.write_text(json.dumps({"config": data, "report": report}, indent=1))
    echo(f"bed settled: {report.get('grains', '?')} grains, t = {t:.4g} s ({step} steps)")
    return run


# ------------------------------------------------------------------ keep folder
def _copy(source, target, names):
    """Copy the files ``names`` (paths relative to ``source``) that ``source`` holds to
    the same places under ``target``; a folder among them is copied whole."""
    source, target = pathlib.Path(source), pathlib.Path(target)
    for name in names:
        path = source / name
        if path.is_dir():
            shutil.copytree(path, target / name, dirs_exist_ok=True)
        elif path.is_file():
            (target / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(path, target / name)


def _bed_config(folder):
    record = pathlib.Path(folder) / "bed.json"
    return json.loads(record.read_text())["config"] if record.exists() else None


def restore_bed(keep, bed, data):
    """Bring the settled bed of the keep folder's ``keep``/bed into ``bed`` when ``bed``
    holds none; ValueError when the kept bed is of another config than ``data``."""
    kept = pathlib.Path(keep) / "bed"
    config = _bed_config(kept)
    if config is None or not (kept / "settled.h5").exists():
        return
    if config != json.loads(json.dumps(data)):
        raise ValueError(f"--keep {keep} holds a bed of another config: choose another "
                         "keep folder")
    if _bed_config(bed) is None or not (pathlib.Path(bed) / "settled.h5").exists():
        _copy(kept, bed, BED_FILES)
    elif not _same_grains(kept / "settled.h5", pathlib.Path(bed) / "settled.h5"):
        raise ValueError(f"{bed} and --keep {keep} hold two different settlings of the "
                         "same config (on machines of two kinds, say): the kept runs start "
                         "from the kept one; remove the out folder's bed or choose another "
                         "keep folder")


def _same_grains(first, second):
    """True when the checkpoints ``first`` and ``second`` hold the same grain
    positions."""
    import h5py

    with h5py.File(first, "r") as a, h5py.File(second, "r") as b:
        return np.array_equal(a["grains/positions"][...], b["grains/positions"][...])


def run_files(folder):
    """The files of a finished study run in ``folder`` that a keep folder holds:
    RUN_FILES, the residual displacements of its last cycle and its relaxations."""
    from ..protocols.cyclic import RELAXATIONS

    record = json.loads((pathlib.Path(folder) / "study_run.json").read_text())
    return RUN_FILES + (record["residual_file"], RELAXATIONS)


def restore_run(keep, folder):
    """Bring the finished run ``keep``/runs/<name> into ``folder`` (its name) when
    ``folder`` holds no finished run; run_from_bed then reuses it if its settings are
    the study's, and runs it again otherwise."""
    kept = pathlib.Path(keep) / "runs" / pathlib.Path(folder).name
    if (kept / "study_run.json").exists() and not (pathlib.Path(folder) /
                                                   "study_run.json").exists():
        files = run_files(kept)
        if (kept / files[len(RUN_FILES)]).exists():     # its residuals: else run it again
            _copy(kept, folder, files)


def keep_run(folder, keep):
    """Put the record of the finished run in ``folder`` into ``keep``/runs/<name>."""
    folder = pathlib.Path(folder)
    _copy(folder, pathlib.Path(keep) / "runs" / folder.name, run_files(folder))


# ------------------------------------------------------------------ one run
def refuse_other_settings(folder, settings, perturbation=0.0):
    """ValueError when the run directory ``folder`` holds a run, finished or stopped to
    be resumed, made with other protocol ``settings`` or another ``perturbation`` [m]
    than the study now asks for: run_from_bed would delete it to start again, and a
    finished run of a thousand cycles is hours of CPU.  The message names the settings
    that differ; another --out (the bed and the runs to keep copied in) keeps both."""
    folder = pathlib.Path(folder)
    for record_file in (folder / "study_run.json", folder / PARTIAL):
        if record_file.exists():
            record = json.loads(record_file.read_text())
            break
    else:
        return
    if record_file.name == PARTIAL and not record.get("closed"):
        return                              # its time unknown: it starts again anyway
    before = {**record["settings"], "perturbation_m": record.get("perturbation_m", 0.0)}
    now = {**settings, "perturbation_m": perturbation}
    differ = sorted(k for k in before.keys() | now.keys() if before.get(k) != now.get(k))
    if differ:
        state = "finished" if record_file.name == "study_run.json" else "stopped"
        changes = ", ".join(f"{k} {before.get(k)!r} -> {now.get(k)!r}" for k in differ)
        raise ValueError(
            f"{folder} holds a {state} run made with other settings ({changes}); it would "
            "be deleted to start again: give the study another --out (copy the bed "
            "and the runs to keep into it) or remove that run folder")


def run_from_bed(bed, settings, folder, echo=print, threads=None, perturbation=0.0):
    """The cycles of one study run in the run directory ``folder``: the bed's resolved
    config with the protocol ``settings`` (and no figures), its meta data, time series
    and settled checkpoint copied there (with ``perturbation`` [m] > 0, one grain of it
    moved by that much: perturb), then ``runner.resume``.  Returns the record of the
    run (study_run.json): results, path, final state measures and times."""
    from ..config import dumps, validate
    from ..config.load import read_toml

    bed, folder = pathlib.Path(bed), pathlib.Path(folder)
    done, partial = folder / "study_run.json", folder / PARTIAL
    same = {"settings": settings, "perturbation_m": perturbation}
    if done.exists():
        record = json.loads(done.read_text())
        if record["settings"] == settings \
                and record.get("perturbation_m", 0.0) == perturbation:
            echo(f"{folder.name}: reusing the finished run")
            return record
    spent = json.loads(partial.read_text()) if partial.exists() and not done.exists() \
        else {}
    if spent.get("closed") and all(spent.get(k) == v for k, v in same.items()):
        echo(f"{folder.name}: resuming from its checkpoint ({spent['cpu_s']:.1f} s CPU "
             f"in {spent['sessions']} session(s) before)")
        return _timed_resume(folder, settings, perturbation, spent, echo, threads)
    if folder.exists():
        shutil.rmtree(folder)
    data = read_toml(bed / "run" / "config.toml")
    data["protocol"].update(settings)
    data["output"]["figures"] = False
    data["protocol"]["residuals"] = True
    config = validate(data, f"settlement study run {folder.name}")
    (folder / "checkpoints").mkdir(parents=True)
    (folder / "config.toml").write_text(dumps(config))
    shutil.copy(bed / "run" / "meta.json", folder / "meta.json")
    shutil.copy(bed / "run" / "series.csv", folder / "series.csv")
    shutil.copy(bed / "settled.h5", folder / "checkpoints" / "checkpoint.h5")
    if perturbation:
        grain = perturb(folder / "checkpoints" / "checkpoint.h5", perturbation)
        echo(f"{folder.name}: grain {grain} moved by {perturbation:.3g} m")
    if (bed / "run" / "vtk").exists():
        shutil.copytree(bed / "run" / "vtk", folder / "vtk")
    echo(f"{folder.name}: {settings}")
    return _timed_resume(folder, settings, perturbation,
                         {"cpu_s": 0.0, "wall_s": 0.0, "steps": 0, "sessions": 0}, echo,
                         threads)


def _timed_resume(folder, settings, perturbation, spent, echo, threads):
    """``runner.resume`` of the study run in ``folder``, timed; ``spent``: the CPU and
    wall times [s], steps and sessions of its earlier sessions.  Interrupted by a signal
    (runner.RunInterrupted: its checkpoint written), the times so far go to
    study_partial.json, marked closed, and the next call resumes the run from its
    checkpoint, adding them up; a session that ends otherwise (killed, crashed) leaves
    the file open, and the run then starts again from the bed, its time being unknown.
    Returns the record of the finished run (study_run.json)."""
    from ..runner import RunInterrupted, resume

    folder = pathlib.Path(folder)
    partial = folder / PARTIAL
    base = {"settings": settings, "perturbation_m": perturbation}
    partial.write_text(json.dumps({**base, **spent, "closed": False}, indent=1))
    start = _checkpoint_step(folder)
    cpu, wall = time.process_time(), time.perf_counter()
    try:
        results = resume(folder, show_progress=False, echo=lambda *a: None, threads=threads)
    except RunInterrupted:
        partial.write_text(json.dumps(
            {**base, "cpu_s": spent["cpu_s"] + time.process_time() - cpu,
             "wall_s": spent["wall_s"] + time.perf_counter() - wall,
             "steps": spent["steps"] + _checkpoint_step(folder) - start,
             "sessions": spent["sessions"] + 1, "closed": True}, indent=1))
        raise
    cpu = spent["cpu_s"] + time.process_time() - cpu
    wall = spent["wall_s"] + time.perf_counter() - wall
    record = {**base, "cpu_s": cpu, "wall_s": wall, "sessions": spent["sessions"] + 1,
              "steps": (results.get("steps_this_session") or 0) + spent["steps"],
              **final_state(folder, results)}
    (folder / "study_run.json").write_text(json.dumps(record, indent=1, default=float))
    partial.unlink()
    echo(f"{folder.name}: {cpu:.1f} s CPU, settlement {1e3 * record['settlement_m']:.4g} mm"
         f" at cycle {record['cycle']}, coordination {record['coordination']:.3f}")
    return record


def _checkpoint_step(folder):
    """The engine step of the newest checkpoint of the run directory ``folder``."""
    from ..output import checkpoint

    return int(checkpoint.latest(pathlib.Path(folder) / "checkpoints", warn=lambda *a: None)[2])


def settlement_path(results):
    """[(cycle, settlement [m], source)] of a cyclic run's results, by cycle: its
    computed cycles ("computed"; "corrected" for a cycle whose record holds the
    correction of the jump checked at its end, protocol.jump_correction) and the ends
    of its extrapolations ("extrapolated")."""
    corrected = {j["checked_at_cycle"] for j in results.get("extrapolations", [])
                 if "correction_m" in j}
    path = [(r["cycle"], r["settlement_m"],
             "corrected" if r["cycle"] in corrected else "computed")
            for r in results["cycles"]]
    path += [(j["to_cycle"], j["settlement_m"], "extrapolated")
             for j in results.get("extrapolations", [])]
    return sorted(path)


def contact_coordination(positions, radii, free=None):
    """Z = 2 C / N_free [-], C the grain pairs with |r_i - r_j| < R_i + R_j (positions
    (N, 3) [m], radii (N,) [m]), N_free the free grains (``free`` (N,) bool, default
    all)."""
    from scipy.spatial import cKDTree

    pairs = cKDTree(positions).query_pairs(2.0 * float(np.max(radii)), output_type="ndarray")
    i, j = pairs[:, 0], pairs[:, 1]
    touching = np.linalg.norm(positions[i] - positions[j], axis=1) < radii[i] + radii[j]
    n = len(radii) if free is None else int(np.sum(free))
    return float(2.0 * np.count_nonzero(touching) / max(1, n))


def final_state(folder, results):
    """Measures of a finished study run at its last cycle N: cycle, settlement [m],
    coordination (contact_coordination of the final checkpoint), the residual file of
    cycle N, the path, the numbers of computed and extrapolated cycles, of the jumps
    undone by the check (jump_tolerance) and of the cycles computed after them, which
    the run then computed again, and the relaxations' iterations and largest overlap
    over the radius after them."""
    from ..output import checkpoint

    arrays, _, _, _ = checkpoint.latest(pathlib.Path(folder) / "checkpoints")
    path = settlement_path(results)
    cycle, settlement, source = path[-1]
    jumps = results.get("extrapolations", [])
    undone = results.get("rejected_extrapolations", [])
    fixed = arrays.get("grains/fixed")
    return {"cycle": cycle, "settlement_m": settlement, "last_cycle": source,
            "coordination": contact_coordination(
                arrays["grains/positions"], arrays["grains/radii"],
                None if fixed is None else np.asarray(fixed) == 0),
            "residual_file": f"residuals/cycle_{cycle:06d}.npy",
            "path": [list(p) for p in path],
            "coordination_path": [[r["cycle"], r["coordination"]] for r in results["cycles"]],
            "computed_cycles": len(results["cycles"]),
            "extrapolated_cycles": sum(j["to_cycle"] - j["from_cycle"] for j in jumps),
            "undone_jumps": len(undone),
            "undone_cycles": sum(j["checked_at_cycle"] - j["to_cycle"] for j in undone),
            "relaxation_iterations": sum(j["relaxation_iterations"] for j in jumps),
            "largest_overlap_after": max((j["largest_overlap_after"] for j in jumps),
                                         default=None),
            "relaxed": all(j["relaxed"] for j in jumps)}


# ------------------------------------------------------------------ comparison
def compare(run, full, run_dir, full_dir):
    """The errors of ``run`` against ``full`` (study_run.json records, their run
    directories) at the last cycle, and the gained time (module docstring)."""
    u_full = np.load(pathlib.Path(full_dir) / full["residual_file"])
    u_run = np.load(pathlib.Path(run_dir) / run["residual_file"])
    reference = {c: s for c, s, _ in full["path"]}
    path_error = max(abs(s - reference[c]) / abs(reference[c]) for c, s, _ in run["path"]
                     if c in reference and reference[c] != 0)
    gained = (full["cpu_s"] - run["cpu_s"]) / run["cpu_s"]
    return {"settlement_error": abs(run["settlement_m"] - full["settlement_m"])
            / abs(full["settlement_m"]),
            "coordination_error": abs(run["coordination"] - full["coordination"])
            / full["coordination"],
            "configuration_error": relative_error(u_full, u_run),
            "path_error": path_error,
            "gained_time_percent": 100.0 * gained,
            "speedup": full["cpu_s"] / run["cpu_s"],
            "cycles_per_hour": 3600.0 * run["cycle"] / run["cpu_s"]}


# ------------------------------------------------------------------ the study
_STOPPED = None         # a worker's event: set once the study is interrupted


def _worker_start(stopped):
    global _STOPPED
    _STOPPED = stopped


def _worker_run(bed, settings, folder, threads, perturbation):
    """run_from_bed in a study's worker, unless the study was interrupted before this
    run started (then RunInterrupted, nothing written)."""
    from ..runner import RunInterrupted

    if _STOPPED.is_set():
        raise RunInterrupted(signal.SIGTERM, folder, 0.0)
    return run_from_bed(bed, settings, folder, threads=threads, perturbation=perturbation)


@contextlib.contextmanager
def _signals_to_workers(stopped):
    """While a study's runs go on in worker processes, SIGTERM and SIGINT received by
    the study set ``stopped`` (no queued run starts) and are sent on to every worker,
    whose run then writes its checkpoint and stops (runner.RunInterrupted) as a run
    alone does; a signal to the study alone would otherwise leave its workers running
    on, and a study started again would compute the same runs twice into the same
    folders.  Main thread only."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def forward(signum, frame):
        stopped.set()
        for child in multiprocessing.active_children():
            os.kill(child.pid, signum)

    saved = {sig: signal.signal(sig, forward) for sig in (signal.SIGTERM, signal.SIGINT)}
    try:
        yield
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)


def study_plan(*, quick=False, base=None, grains=None, cycles=None, initial_cycles=None,
               ks=None, hs=None, k_fixed=None, h_fixed=None, estimator="shenton",
               mode="fully", overrides=None, replicas=0, procedure_replicas=0):
    """What run_settlement_study (its arguments and defaults) computes: the bed's config
    dict, the runs {name: protocol settings}, the families {family: [names]} and the
    number of cycles N."""
    q = quick
    cycles = cycles or (8 if q else 100)
    initial_cycles = initial_cycles or (2 if q else 10)
    ks = tuple(ks or ((2, 3) if q else (10, 20, 40)))
    hs = tuple(hs or ((2, 3) if q else (10, 20, 40)))
    k_fixed, h_fixed = k_fixed or (3 if q else 40), h_fixed or (2 if q else 10)
    if mode not in MODES:
        raise ValueError(f"mode {mode!r}: choose one of {', '.join(MODES)}")
    if base is None:
        base = QUICK if q else TABLE1
        if grains is None and not q:
            grains = 430
    data = study_config(base, grains, {**MODES[mode], **(overrides or {})})
    procedure = {key: data["protocol"].pop(key) for key in PROCEDURE_KEYS
                 if key in data["protocol"]}
    runs, families = plan(cycles, initial_cycles, ks, hs, k_fixed, h_fixed, estimator,
                          replicas, procedure_replicas)
    runs = {name: settings if settings["extrapolation"] == "none"
            else {**procedure, **settings}
            for name, settings in runs.items()}
    return data, runs, families, cycles


def study_standing(out, keep=None, now=None, **arguments):
    """Where each run of the study that run_settlement_study(out, keep=keep,
    **arguments) computes stands, from the files alone (nothing runs, nothing is
    written): the bed's settling ("bed"), then every run, each a dict with its
    ``name`` and ``state``: "finished" (its study_run.json in ``out``, or only in the
    keep folder: ``kept``), "started" (a log in ``out``: running, or interrupted and
    resumed by the next study command; with what output.rundir.progress reads) or
    "not started"."""
    from ..output.rundir import progress

    out = pathlib.Path(out)
    runs = study_plan(**arguments)[1]
    folders = {"bed": (out / "bed" / "bed.json", out / "bed" / "run",
                       None if keep is None else pathlib.Path(keep) / "bed" / "bed.json")}
    for name in runs:
        folders[name] = (out / "runs" / name / "study_run.json", out / "runs" / name,
                         None if keep is None else
                         pathlib.Path(keep) / "runs" / name / "study_run.json")
    rows = []
    for name, (done, folder, kept) in folders.items():
        if done.exists():
            row = {"state": "finished"}
        elif kept is not None and kept.exists():
            row = {"state": "finished", "kept": True}
        else:
            news = progress(folder, now)
            row = {"state": "not started"} if news is None else {"state": "started", **news}
        rows.append({"name": name, **row})
    return rows


def run_settlement_study(out, *, quick=False, base=None, grains=None, cycles=None,
                         initial_cycles=None, ks=None, hs=None, k_fixed=None, h_fixed=None,
                         estimator="shenton", mode="fully", overrides=None, threads=None,
                         jobs=1, replicas=0, procedure_replicas=0, keep=None,
                         echo=print):
    """Settle one bed, run full DEM and the procedure's k and h families from it (module
    docstring) into ``out``; write summary.csv, paths.csv, summary.json and the figures
    settlement_paths.png (Fig. 11) and settlement_errors.png (Fig. 12-13).

    base: config dict (default Table 1, or the soft 120-grain bed QUICK with ``quick``);
    grains: grain count (default 430, in a cylinder of radius 24.9 mm; quick: 120);
    cycles: N (default 100; quick 8); initial_cycles k_i (10; quick 2); ks, hs: the
    families' k and h (10, 20, 40; quick 2, 3) at h = h_fixed (10; quick 2) and
    k = k_fixed (40; quick 3); estimator linear or shenton; mode: a MODES entry whose
    protocol settings go on the base; overrides: {dotted key: value} applied last;
    threads: numba threads of each run (default the bed's); jobs: runs at a time, each
    in its own process (their CPU times are then measured side by side, on a machine
    with at least ``jobs`` free cores); replicas: full DEM runs of the bed with one
    grain moved by 1, 2, ... nm (perturb), compared with full DEM like the procedure's
    runs: the spread of their errors ("noise" in the summary) is how far apart two
    computations of the same bed land, the floor below which a procedure's error means
    nothing; procedure_replicas: every procedure run repeated from the beds of the
    first full DEM replicas, each compared with full DEM of its own bed, and the
    pairs' mean error with its standard error ("ensembles", ensemble) written with
    the figure settlement_ensemble.png and the table ensembles.csv; keep: a keep folder
    (module docstring) whose bed and finished runs are taken, and into which the bed,
    each run as it finishes and the tables and figures go.  Returns the summary
    dict."""
    out = pathlib.Path(out)
    data, runs, families, cycles = study_plan(
        quick=quick, base=base, grains=grains, cycles=cycles, initial_cycles=initial_cycles,
        ks=ks, hs=hs, k_fixed=k_fixed, h_fixed=h_fixed, estimator=estimator, mode=mode,
        overrides=overrides, replicas=replicas, procedure_replicas=procedure_replicas)
    out.mkdir(parents=True, exist_ok=True)
    bed = out / "bed"
    if keep is not None:
        keep = pathlib.Path(keep)
        restore_bed(keep, bed, data)
        for name in runs:
            restore_run(keep, out / "runs" / name)
    for name, settings in runs.items():
        refuse_other_settings(out / "runs" / name, settings, perturbation_of(name))
    prepare_bed(data, bed, echo=echo)
    if keep is not None:
        _copy(bed, keep / "bed", BED_FILES)
    records = {}
    if jobs > 1:
        import concurrent.futures

        context = multiprocessing.get_context("spawn")
        stopped = context.Event()
        with concurrent.futures.ProcessPoolExecutor(
                jobs, mp_context=context, initializer=_worker_start,
                initargs=(stopped,)) as pool, _signals_to_workers(stopped):
            futures = {pool.submit(_worker_run, bed, settings, out / "runs" / name,
                                   threads, perturbation_of(name)): name
                       for name, settings in runs.items()}
            try:
                for future in concurrent.futures.as_completed(futures):
                    records[futures[future]] = future.result()
                    if keep is not None:
                        keep_run(out / "runs" / futures[future], keep)
            except BaseException:
                stopped.set()                   # no run starts after an interruption
                for future in futures:
                    future.cancel()
                raise
        records = {name: records[name] for name in runs}
    else:
        for name, settings in runs.items():
            records[name] = run_from_bed(bed, settings, out / "runs" / name, echo=echo,
                                         threads=threads, perturbation=perturbation_of(name))
            if keep is not None:
                keep_run(out / "runs" / name, keep)
    rows = []
    for name, record in records.items():
        reference = reference_of(name)
        errors = compare(record, records[reference], out / "runs" / name,
                         out / "runs" / reference)
        s = runs[name]
        rows.append({"run": name, "families": "+".join(f for f in families
                                                        if name in families[f]) or "reference",
                     "reference": reference,
                     "estimator": s["extrapolation"],
                     "initial_cycles": s.get("initial_cycles", ""),
                     "computed_cycles_k": s.get("computed_cycles", ""),
                     "extrapolated_cycles_h": s.get("extrapolated_cycles", ""),
                     "cycles": record["cycle"], "cycles_computed": record["computed_cycles"],
                     "cycles_extrapolated": record["extrapolated_cycles"],
                     "undone_jumps": record.get("undone_jumps", 0),
                     "cycles_computed_again": record.get("undone_cycles", 0),
                     "settlement_m": record["settlement_m"],
                     "coordination": record["coordination"],
                     "cpu_s": record["cpu_s"], "wall_s": record["wall_s"], **errors,
                     "relaxation_iterations": record["relaxation_iterations"],
                     "largest_overlap_after": record["largest_overlap_after"]})
    summary = {
        "quick": quick, "mode": mode, "estimator": estimator,
        "overrides": {**MODES[mode], **(overrides or {})},
        "grains": data["grains"]["count"], "cycles": cycles, "jobs": jobs,
        "bed": json.loads((bed / "bed.json").read_text()).get("report", {}),
        "families": families, "runs": {r["run"]: r for r in rows},
        "paths": {name: r["path"] for name, r in records.items()},
        "coordination_paths": {name: r["coordination_path"] for name, r in records.items()},
        "noise": noise([r for r in rows if r["run"] in families["replica"]]),
        "forecast": forecast_floor(records[FULL]["path"], runs.values()),
        "ensembles": {name: ensemble(records, [(name, FULL)] + [
            (replica_name(name, r), replica_name(FULL, r))
            for r in range(1, procedure_replicas + 1)])
            for name in dict.fromkeys(families["k"] + families["h"])}
        if procedure_replicas else {},
        "definitions": {
            "settlement_error": "|s_p(N) - s_full(N)| / s_full(N)",
            "coordination_error": "|Z_p(N) - Z_full(N)| / Z_full(N), Z = 2 C / N of the "
                                  "overlapping grain pairs at cycle N",
            "configuration_error": "E_r = ||u_full - u_p|| / ||u_full|| (Karrech Eq. 22), "
                                   "residual displacements at cycle N",
            "path_error": "max over the run's cycles c of |s_p(c) - s_full(c)| / s_full(c)",
            "gained_time_percent": "(t_full - t_p) / t_p x 100, t the CPU time [s] of the "
                                   "cycles (settling excluded)",
            "speedup": "t_full / t_p",
            "noise": "mean and largest of each error over the replicas, full DEM runs of "
                     "the bed with one grain moved by 1, 2, ... nm",
            "forecast": "full DEM's settlement forecast from its own last k cycles by the "
                        "linear estimator (Eq. 16), h cycles ahead, from cycle k_i on "
                        "(analysis.settlement.forecast_errors): root mean square and mean "
                        "of the relative errors, for each k and h of the runs and h = "
                        f"{', '.join(map(str, FORECAST_HORIZONS))}",
            "reference": "the full DEM run a run is compared with: that of its own bed "
                         "for a procedure replica, of the unperturbed bed otherwise",
            "ensembles": "per procedure run, its replicas each against full DEM of the "
                         "same bed (ensemble)"}}
    _write_tables(out, rows, records, summary["ensembles"])
    (out / "summary.json").write_text(json.dumps(summary, indent=1, default=float))
    figures(out, summary)
    if keep is not None:
        _copy(out, keep, STUDY_FILES)
    return summary


def forecast_floor(path, settings):
    """{"k<k>_h<h>": {"rms", "mean", "forecasts"}}: the relative errors of forecasting
    full DEM's settlement ``path`` ([(cycle, settlement [m], source)], every cycle) h
    cycles ahead from its last k cycles (analysis.settlement.forecast_errors), from the
    runs' k_i on, for the k and h of the procedure runs among ``settings`` and h in
    FORECAST_HORIZONS (the procedure's h grows); pairs the path is too short for are
    left out.  How well the bed's own past tells its settlement: a floor under the
    error of a procedure's jumps."""
    procedure = [s for s in settings if s["extrapolation"] != "none"]
    if not procedure:
        return {}
    first = min(s["initial_cycles"] for s in procedure) - 1    # record of cycle k_i
    settlement = [s for _, s, _ in sorted(path)]
    floor = {}
    for k in sorted({s["computed_cycles"] for s in procedure}):
        for h in sorted({s["extrapolated_cycles"] for s in procedure} | set(FORECAST_HORIZONS)):
            if first + k + h >= len(settlement):
                continue
            errors = forecast_errors(settlement, k, h, first=first)
            floor[f"k{k}_h{h}"] = {"rms": float(np.sqrt(np.mean(errors**2))),
                                   "mean": float(np.mean(errors)),
                                   "forecasts": int(errors.size)}
    return floor


def noise(rows):
    """{error: (mean, largest)} over the replica rows (settlement, coordination,
    configuration and path errors); empty without replicas."""
    keys = ("settlement_error", "coordination_error", "configuration_error", "path_error")
    if not rows:
        return {}
    return {key: (float(np.mean([r[key] for r in rows])), float(max(r[key] for r in rows)))
            for key in keys}


def path_on_cycles(path, cycles):
    """The settlement [m] of a study path [(cycle, settlement, source)] at ``cycles``,
    linear between the cycles it reports (an extrapolation's jump is linear in the
    cycle for the linear estimator, and is drawn so for Shenton's)."""
    return np.interp(cycles, [p[0] for p in path], [p[1] for p in path])


def ensemble(records, pairs):
    """The procedure against full DEM over replicated beds: ``pairs`` [(procedure run,
    full DEM run of the same bed)] of the study records {name: record}, at least two.
    With d_r = s_p,r - s_f,r the pair's difference in settlement [m]:

    - settlement_bias = mean(d_r(N)) / mean(s_f,r(N)) at the last cycle N, with its
      standard error std(d_r) / sqrt(n) / mean(s_f,r) (the beds differ by nanometres,
      which the load cycles amplify into independent arrangements: each pair is a
      sample); the procedure's own error, which more pairs resolve to any precision;
    - mean_settlement_error = mean(|d_r(N)| / s_f,r(N)): what one run misses by, the
      bias and the chaos of both computations together;
    - full_spread, procedure_spread = std(s_r(N)) / mean(s_f,r(N)): how far apart two
      runs of each land;
    - path_bias (and path_bias_se) at every cycle c = 1..N, each path interpolated
      linearly between the cycles it reports, and its largest magnitude;
    - speedup = sum of full DEM's CPU times / sum of the procedure's."""
    if len(pairs) < 2:
        raise ValueError("an ensemble needs at least two pairs of runs")
    procedure = [records[p] for p, _ in pairs]
    full = [records[f] for _, f in pairs]
    n = len(pairs)
    last = min(r["cycle"] for r in procedure + full)
    cycles = np.arange(1, last + 1)

    s_full = np.array([path_on_cycles(r["path"], cycles) for r in full])
    d = np.array([path_on_cycles(p["path"], cycles) for p in procedure]) - s_full
    mean_full = s_full.mean(axis=0)
    bias = d.mean(axis=0) / mean_full
    worst = int(np.argmax(np.abs(bias)))
    s_proc = s_full[:, -1] + d[:, -1]
    return {"pairs": [list(pair) for pair in pairs], "cycle": int(last),
            "settlement_full_mean_m": float(mean_full[-1]),
            "settlement_procedure_mean_m": float(s_proc.mean()),
            "settlement_bias": float(bias[-1]),
            "settlement_bias_se": float(d[:, -1].std(ddof=1) / math.sqrt(n)
                                        / mean_full[-1]),
            "mean_settlement_error": float(np.mean(np.abs(d[:, -1]) / s_full[:, -1])),
            "full_spread": float(s_full[:, -1].std(ddof=1) / mean_full[-1]),
            "procedure_spread": float(s_proc.std(ddof=1) / mean_full[-1]),
            "path_bias_largest": float(abs(bias[worst])),
            "path_bias_cycle": int(cycles[worst]),
            "path_bias": bias.tolist(),
            "path_bias_se": (d.std(axis=0, ddof=1) / math.sqrt(n) / mean_full).tolist(),
            "speedup": sum(r["cpu_s"] for r in full) / sum(r["cpu_s"] for r in procedure),
            "cpu_full_s": sum(r["cpu_s"] for r in full),
            "cpu_procedure_s": sum(r["cpu_s"] for r in procedure)}


def _write_tables(out, rows, records, ensembles):
    """summary.csv (one row per run), paths.csv (run, cycle, settlement, source) and,
    with procedure replicas, ensembles.csv (one row per procedure run: its ensemble's
    numbers at the last cycle, ensemble)."""
    if ensembles:
        with open(out / "ensembles.csv", "w", newline="") as f:
            table = [{"run": name, "pairs": len(e["pairs"]),
                      **{k: v for k, v in e.items() if not isinstance(v, list)}}
                     for name, e in ensembles.items()]
            writer = csv.DictWriter(f, fieldnames=list(table[0]))
            writer.writeheader()
            writer.writerows(table)
    with open(out / "summary.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    with open(out / "paths.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["run", "cycle", "settlement_m", "source"])
        for name, record in records.items():
            writer.writerows([name, *p] for p in record["path"])


def figures(out, summary):
    """settlement_paths.png: settlement [mm] against the cycle for the k family and the
    h family with full DEM (Karrech Fig. 11); settlement_errors.png: coordination against
    the cycle and the errors in coordination, configuration (E_r) and settlement
    against the gained time (Fig. 12, and Fig. 13 for the partially confined mode);
    settlement_relaxation.png: the overlaps before and after the relaxations of the
    first run of the families that kept them (protocols.cyclic.relaxation_figure,
    Fig. 9).  Returns their paths."""
    from ..figures import subplots

    out = pathlib.Path(out)
    paths, runs, families = summary["paths"], summary["runs"], summary["families"]
    title = (f"{summary['grains']} grains, {summary['mode']} confined, "
             f"{summary['estimator']}, N = {summary['cycles']}")

    def label(name):
        r = runs[name]
        if name.startswith(REPLICA):
            return f"full DEM, a grain moved by {perturbation_of(name) * 1e9:.0f} nm"
        moved = f", a grain moved by {perturbation_of(name) * 1e9:.0f} nm" \
            if perturbation_of(name) else ""
        return (f"k_i={r['initial_cycles']}, k={r['computed_cycles_k']}, "
                f"h={r['extrapolated_cycles_h']}{moved}")

    fig, axes = subplots(1, 2, figsize=(12, 4.5), sharey=True)
    for ax, family, tag in zip(axes, ("k", "h"), ("(a) varying k", "(b) varying h")):
        for r, name in enumerate(families.get("replica", [])):
            c, s, _ = zip(*paths[name])
            ax.plot(c, 1e3 * np.array(s), "-", color="0.6", lw=0.8,
                    label="full DEM, a grain moved by nm" if r == 0 else None)
        c, s, _ = zip(*paths[FULL])
        ax.plot(c, 1e3 * np.array(s), "k-", lw=2, label="full DEM")
        for name in families[family]:
            c, s, src = zip(*paths[name])
            line, = ax.plot(c, 1e3 * np.array(s), "-", lw=1, label=label(name))
            jumps = [k for k, x in enumerate(src) if x == "extrapolated"]
            ax.plot(np.array(c)[jumps], 1e3 * np.array(s)[jumps], "o", color=line.get_color(),
                    mfc="none")
        ax.set(xlabel="cycle", title=tag)
        ax.legend(fontsize=8)
    axes[0].set_ylabel("settlement [mm]")
    fig.suptitle(f"Settlement paths (open marks: extrapolated), {title}")
    fig.tight_layout()
    first = out / "settlement_paths.png"
    fig.savefig(first, dpi=110)

    fig, axes = subplots(1, 4, figsize=(18, 4.2))
    c, z = zip(*summary["coordination_paths"][FULL])
    axes[0].plot(c, z, "k-", lw=2, label="full DEM")
    for name in runs:
        if name != FULL and summary["coordination_paths"][name]:
            c, z = zip(*summary["coordination_paths"][name])
            axes[0].plot(c, z, ".", ms=3, label=label(name))
    axes[0].set(xlabel="cycle", ylabel="coordination number [-] (computed cycles)")
    axes[0].legend(fontsize=7)
    replicas = set(families.get("replica", []))
    procedure = [r for name, r in runs.items() if name != FULL and name not in replicas]
    gained = [r["gained_time_percent"] for r in procedure]
    for ax, key, what in zip(axes[1:], ("coordination_error", "configuration_error",
                                        "settlement_error"),
                             ("coordination number", "configuration E_r (Eq. 22)",
                              "settlement")):
        for r, g in zip(procedure, gained):
            ax.plot(g, 100.0 * r[key], "o")
            ax.annotate(f"k={r['computed_cycles_k']},h={r['extrapolated_cycles_h']}",
                        (g, 100.0 * r[key]), fontsize=7)
        ax.plot([0], [0], "k+")
        if summary.get("noise"):
            ax.axhspan(0.0, 100.0 * summary["noise"][key][1], color="0.85", zorder=0,
                       label="full DEM against itself, a grain moved by nm")
            ax.legend(fontsize=7)
        ax.set(xlabel="gained time (t_full - t_p) / t_p [%]",
               ylabel=f"relative error in {what} [%]")
    fig.suptitle(f"Procedure against full DEM at cycle {summary['cycles']}, {title}")
    fig.tight_layout()
    second = out / "settlement_errors.png"
    fig.savefig(second, dpi=110)
    made = [first, second]
    if summary.get("ensembles"):
        made.append(ensemble_figure(out, summary, label, title))
    from ..protocols.cyclic import RELAXATIONS, relaxation_figure

    relaxed = [name for name in (*families["k"], *families["h"])
               if (out / "runs" / name / RELAXATIONS).is_dir()]
    if relaxed:
        fig = relaxation_figure(out / "runs" / relaxed[0], label(relaxed[0]))
        fig.tight_layout()
        made.append(out / "settlement_relaxation.png")
        fig.savefig(made[-1], dpi=110)
    return made


def ensemble_figure(out, summary, label, title):
    """settlement_ensemble.png: the mean settlement path of full DEM and of each
    procedure run over the replicated beds, each with a band of one spread (left), and
    the bias of each procedure run, its mean difference from full DEM of the same beds
    over full DEM's mean, with a band of one standard error and the lines at +-1 %
    (right)."""
    from ..figures import subplots

    paths = summary["paths"]
    fig, axes = subplots(1, 2, figsize=(13, 4.6))

    def band(names, cycles, color, tag, lw):
        s = 1e3 * np.array([path_on_cycles(paths[r], cycles) for r in names])
        mean, spread = s.mean(axis=0), s.std(axis=0, ddof=1)
        axes[0].plot(cycles, mean, "-", color=color, lw=lw, label=f"{tag}, {len(names)} beds")
        axes[0].fill_between(cycles, mean - spread, mean + spread, color=color, alpha=0.15,
                             lw=0)

    for k, (name, e) in enumerate(summary["ensembles"].items()):
        cycles = np.arange(1, e["cycle"] + 1)
        if k == 0:
            band([f for _, f in e["pairs"]], cycles, "k", "full DEM", 2)
        band([p for p, _ in e["pairs"]], cycles, f"C{k}", label(name), 1.2)
        bias = 100.0 * np.array(e["path_bias"])
        se = 100.0 * np.array(e["path_bias_se"])
        axes[1].plot(cycles, bias, "-", color=f"C{k}",
                     label=f"{label(name)}: {100 * e['settlement_bias']:+.2f} +- "
                           f"{100 * e['settlement_bias_se']:.2f} % at cycle {e['cycle']}, "
                           f"{e['speedup']:.2f}x")
        axes[1].fill_between(cycles, bias - se, bias + se, color=f"C{k}", alpha=0.2, lw=0)
    for y in (-1.0, 1.0):
        axes[1].axhline(y, color="0.5", ls="--", lw=0.8)
    axes[1].axhline(0.0, color="k", lw=0.8)
    axes[0].set(xlabel="cycle", ylabel="settlement [mm] (mean, band: one spread)")
    axes[1].set(xlabel="cycle",
                ylabel="bias: mean(s_p - s_full) / mean(s_full) [%] (band: one s.e.)")
    for ax in axes:
        ax.legend(fontsize=7)
    fig.suptitle(f"The procedure over several beds, {title}")
    fig.tight_layout()
    path = pathlib.Path(out) / "settlement_ensemble.png"
    fig.savefig(path, dpi=110)
    return path
