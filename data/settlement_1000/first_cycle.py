"""The cycles after a jump made with full DEM's own positions, to tell what in a jump
moves the bed and what in the extrapolation does.

    python first_cycle.py STUDY OUT C0[,C0...] H AFTER VARIANT[,VARIANT...]

STUDY is a settlement study folder whose full DEM run kept its residuals (``graindyn
study settlement``: runs/full_dem/residuals/cycle_NNNNNN.npy, cycles.csv); OUT a folder
for the states.  The bed of the study is loaded through its full DEM run's config, its
cycles computed again up to each C0 (the same numbers as the stored run, checked on
the plate's height) and the whole state kept (OUT/cycleC0.pkl).  From each state:

* ``continue``: AFTER cycles computed on, as full DEM did (a check: the same path);
* ``rest``: the velocities zeroed, then AFTER cycles;
* ``inplace:RELAXATION``: the bed relaxed where it stands (no jump) as the procedure
  relaxes it (``excess`` or ``excess_walls``: gravity off, one weight per mean radius
  holding each grain, the overlaps at the start allowed), then AFTER cycles;
* ``exact:WIDTH:RELAXATION``: every grain put where full DEM has it H cycles on (its
  increment averaged over WIDTH mean radii first, as the procedure smooths its
  extrapolation; 0: unsmoothed), the plate where full DEM has it, relaxed as the
  procedure relaxes an extrapolation (``excess`` or ``excess_walls``; allowed: the
  positions at C0; the contacts' history kept;
  ``none``: not relaxed, the grains only put there, their velocities zeroed), then
  AFTER cycles from cycle C0 + H;
* ``fit:WIDTH:RELAXATION``: the same, but every grain and the plate put where the
  linear estimator (Eq. 16) fitted to full DEM's cycles C0 - 10 to C0 extrapolates
  them H cycles on, as the procedure's jump does (k = 10);
* ``chain:N:WIDTH:RELAXATION[:SOURCE]``: N such jumps in succession, each followed by
  AFTER cycles (11: the restart cycle and a window of 10), the second and later ones
  fitted to the branch's own last 10 cycles, as the procedure's rounds are (SOURCE
  ``own``, the default), or to full DEM's last 10 cycles before the branch's cycle
  (``full``: the increments full DEM makes there, put on the branch's grains), or
  made of full DEM's own increments over the H cycles the jump spans (``exact``: no
  estimate at all), or fitted to the mean rates of the branch's last two windows
  (``pooled``: the one before the last jump and the one after it).  The first three
  tell a bed slowed by jumps in succession from one slowed by what its own window
  reads; each jump's window is printed too, as the mean descent rate of the bottom,
  middle and top third of the grains and their mean lateral rate, against full
  DEM's over the same cycles.

Prints, for each state and variant, the plate's descent [um] in each cycle after, and
full DEM's over the same cycles.  The relaxation tolerance is the study's (1e-3
weights); numba's threads are chosen as for a run of the bed (one below 1000 grains)."""
import copy
import csv
import pathlib
import pickle
import shutil
import sys

import numpy as np

from graindyn import _threads as threading_policy
from graindyn.analysis.settlement import smooth_increments
from graindyn.config.load import load
from graindyn.output.rundir import RunDirectory
from graindyn.runner import restored

WINDOW = 10     # computed cycles of the procedure's window [-]
SOURCES = ("own", "full", "exact", "pooled")    # what a chain's later jumps are made of


def main(study, out, starts, h, after, variants):
    for variant in variants:        # refused before any cycle is computed
        kind, *args = variant.split(":")
        if kind == "chain" and len(args) > 3 and args[3] not in SOURCES:
            raise SystemExit(f"chain source {args[3]!r}: one of {', '.join(SOURCES)}")
    full = study / "runs" / "full_dem"
    plate_full = {int(r["cycle"]): float(r["plate_height_m"])
                  for r in csv.DictReader(open(full / "cycles.csv"))}
    folder = out / "run"
    if not folder.exists():
        (folder / "checkpoints").mkdir(parents=True)
        shutil.copy(full / "config.toml", folder / "config.toml")
        shutil.copy(study / "bed" / "run" / "meta.json", folder / "meta.json")
        shutil.copy(study / "bed" / "settled.h5", folder / "checkpoints" / "checkpoint.h5")
    protocol, engine, meta, _, _ = restored(RunDirectory(folder), load(folder / "config.toml"))
    threading_policy.use(0, engine.state.n)     # as the study's runs: one thread here
    protocol.log, protocol.folder = (lambda line: None), None
    set_motion = engine.set_motion        # the plate stays a piston between the calls
    engine.set_motion = lambda k, m: None if m.kind == "fixed" else set_motion(k, m)
    cycles = protocol.phases[-1]
    plate = engine.walls.index("plate")
    missing = [c for c in starts if not (out / f"cycle{c}.pkl").exists()]
    if missing:
        states = meta["protocol"]["states"]
        for phase in protocol.phases[meta["protocol"]["phase"]:-1]:
            phase.run(engine, states.setdefault(phase.name, {}))
        state = states.setdefault(cycles.name, {})
        for c in sorted(missing):
            cycles.p.cycles = c
            cycles.run(engine, state)
            height = state["rows"][-1]["plate_height_m"]
            if height != plate_full[c]:
                raise SystemExit(f"cycle {c}: plate at {height} m, full DEM {plate_full[c]}")
            with open(out / f"cycle{c}.pkl", "wb") as f:
                pickle.dump((engine.snapshot(), copy.deepcopy(state)), f)

    def branch(snapshot, state0, prepare):
        engine.restore(snapshot)
        state = copy.deepcopy(state0)
        start = prepare(state)
        heights = [cycles._plate(engine, plate)]       # where the jump put the plate
        cycles.p.cycles = start + after
        cycles.run(engine, state)
        heights += [r["plate_height_m"] for r in state["rows"] if r["cycle"] > start]
        return start, -np.diff(heights)

    def relax(state, grains, offset, allowed, relaxation, to_cycle):
        before = engine.walls.offset.copy()
        engine.place_wall(plate, offset)
        if relaxation == "none":        # every overlap allowed: the grains only put there
            allowed, before = grains, engine.walls.offset.copy()
        engine.relax(fixed=engine.state.fixed != 0, force_tolerance=1e-3, gravity=False,
                     anchor=1.0, start=grains, keep_contacts=True, allowed=allowed,
                     allowed_walls=None if relaxation == "excess" else before)
        state["cycle"] = to_cycle
        return to_cycle

    def chain(snapshot, state0, c0, jumps, width, relaxation, source):
        """``jumps`` jumps in succession, each fitted as the procedure fits it to the
        last WINDOW cycles (full DEM's before the first, after the others the branch's
        own, or full DEM's with ``source == "full"``; full DEM's own increments over
        the jump with ``source == "exact"``), carried H cycles, relaxed, then AFTER
        cycles computed (``pooled``: each jump after the first fitted to the mean rates of
        the branch's last two windows, the one before the last jump's and the one after
        it); prints each, and the profile of the window after it against full DEM's over
        the same cycles."""
        engine.restore(snapshot)
        state = copy.deepcopy(state0)
        reference = np.asarray(state0["reference"])

        def full_window(c, span):
            """Full DEM's positions and plate at cycles c - WINDOW and c (span
            "window") or c and c + H (span "ahead"), and the factor that turns their
            difference into the jump's increments."""
            ends = (c - WINDOW, c) if span == "window" else (c, c + h)
            positions = [reference + np.load(full / "residuals" / f"cycle_{i:06d}.npy")
                         for i in ends]
            return positions, [plate_full[i] for i in ends], \
                h / WINDOW if span == "window" else 1.0

        def profile(ends):
            """A window's increments [um per cycle], smoothed as the jump smooths
            them about the branch's grains: the mean descent of the bottom, middle and
            top third of the grains by height, and the mean horizontal length."""
            here = engine.state.positions
            rate = (ends[1] - ends[0]) / WINDOW
            if width > 0:
                rate = smooth_increments(
                    here, rate, width * float(np.mean(engine.state.radii)),
                    planes=[(p.index, p.at) for p in cycles.vessel.symmetry])
            thirds = np.array_split(np.argsort(here[:, -1]), 3)
            return " ".join(f"{-1e6 * rate[t, -1].mean():.3f}" for t in thirds) + \
                f" lateral {1e6 * np.hypot(rate[:, 0], rate[:, 1]).mean():.3f}"

        label = f"{c0} chain" + ("" if source == "own" else f"-{source}")
        window, plates, scale = full_window(c0, "window")
        earlier = None          # the window before this one, for source == "pooled"
        cycle = c0
        for j in range(jumps):
            here = engine.state.positions.copy()
            field, descent = window[1] - window[0], plates[1] - plates[0]
            if source == "pooled" and earlier is not None:  # the two windows' mean rates
                field = 0.5 * (field + earlier[0][1] - earlier[0][0])
                descent = 0.5 * (descent + earlier[1][1] - earlier[1][0])
            increments = field * scale
            if width > 0:
                increments = smooth_increments(
                    here, increments, width * float(np.mean(engine.state.radii)),
                    planes=[(p.index, p.at) for p in cycles.vessel.symmetry])
            offset = engine.walls.offset[plate].copy()
            offset[-1 if cycles.vessel.dim == 3 else 1] += descent * scale
            cycle = relax(state, here + increments, offset, here, relaxation, cycle + h)
            heights, positions = [cycles._plate(engine, plate)], {}
            for _ in range(after):
                cycles.p.cycles = cycle + 1
                cycles.run(engine, state)
                cycle += 1
                heights.append(state["rows"][-1]["plate_height_m"])
                positions[cycle] = engine.state.positions.copy()
            reference_descent = -np.diff([plate_full[c] for c in
                                          range(cycle - after, cycle + 1)])
            print(f"{label} jump {j + 1} to {cycle - after}: "
                  + " ".join(f"{1e6 * d:.2f}" for d in -np.diff(heights)) + " | "
                  + " ".join(f"{1e6 * d:.2f}" for d in reference_descent), flush=True)
            own = [positions[cycle - WINDOW], positions[cycle]]
            print(f"{label} window {j + 1} field: {profile(own)} | full DEM's: "
                  f"{profile(full_window(cycle, 'window')[0])}", flush=True)
            if source in ("full", "exact"):
                window, plates, scale = full_window(
                    cycle, "window" if source == "full" else "ahead")
            else:
                earlier = (window, plates)
                window, plates = own, [heights[-1 - WINDOW], heights[-1]]

    print("C0 variant: descent in each cycle after [um] | full DEM's")
    for c0 in starts:
        with open(out / f"cycle{c0}.pkl", "rb") as f:
            snapshot, state0 = pickle.load(f)
        reference = np.asarray(state0["reference"])
        for variant in variants:
            kind, *args = variant.split(":")
            if kind == "chain":
                chain(snapshot, state0, c0, int(args[0]), float(args[1]), args[2],
                      args[3] if len(args) > 3 else "own")
                continue
            if kind == "continue":
                prepare = lambda state: state["cycle"]
            elif kind == "rest":
                def prepare(state):
                    engine.state.velocities[:] = 0.0
                    engine.state.angular_velocities[:] = 0.0
                    return state["cycle"]
            elif kind == "inplace":
                def prepare(state, relaxation=args[0]):
                    here = engine.state.positions.copy()
                    return relax(state, here, engine.walls.offset[plate].copy(), here,
                                 relaxation, state["cycle"])
            elif kind in ("exact", "fit"):
                def prepare(state, width=float(args[0]), relaxation=args[1], fit=kind == "fit"):
                    here = engine.state.positions.copy()
                    if fit:
                        window = [np.load(full / "residuals" / f"cycle_{c:06d}.npy")
                                  for c in (c0 - WINDOW, c0)]
                        increments = (window[1] - window[0]) * h / WINDOW
                    else:
                        increments = reference + np.load(
                            full / "residuals" / f"cycle_{c0 + h:06d}.npy") - here
                    if width > 0:
                        increments = smooth_increments(
                            here, increments, width * float(np.mean(engine.state.radii)),
                            planes=[(p.index, p.at) for p in cycles.vessel.symmetry])
                    offset = engine.walls.offset[plate].copy()
                    offset[-1 if cycles.vessel.dim == 3 else 1] += \
                        (plate_full[c0] - plate_full[c0 - WINDOW]) * h / WINDOW if fit \
                        else plate_full[c0 + h] - plate_full[c0]
                    return relax(state, here + increments, offset, here, relaxation, c0 + h)
            else:
                raise SystemExit(f"unknown variant {variant}")
            start, descent = branch(snapshot, state0, prepare)
            reference_descent = -np.diff([plate_full[c] for c in range(start, start + after + 1)])
            print(f"{c0} {variant}: " + " ".join(f"{1e6 * d:.2f}" for d in descent) + " | "
                  + " ".join(f"{1e6 * d:.2f}" for d in reference_descent), flush=True)


if __name__ == "__main__":
    a = sys.argv[1:]
    main(pathlib.Path(a[0]), pathlib.Path(a[1]), [int(c) for c in a[2].split(",")],
         int(a[3]), int(a[4]), a[5].split(","))
