"""The event-driven engine's speed on elastic gases, and side by side with the soft engine
on one dilute cooling gas.

    python benchmarks/event_driven_gas.py rates [--grains 10000 100000] [--collisions 20]
    python benchmarks/event_driven_gas.py versus [--grains 2000] [--time 0.05]
    python benchmarks/event_driven_gas.py peer EDMD_DIR [--cells 14 29] [--collisions 20]
        [--repeats 1]

rates: an elastic gas of smooth spheres (3D) or disks (2D) of diameter 1 mm at
packing fractions 0.05 and 0.3 in a periodic box, inserted at random and numbered cell
by cell as prepare.fill numbers them, Maxwellian at T = 1e-9 J; after
5 collisions per grain untimed, the engine runs --collisions per grain (sized by
Enskog's rate) and the collisions per second of wall time, the events per collision
and the peak memory of the process are printed, one thread.

versus: the gas of examples/cooling_gas.toml (packing fraction 0.05, restitution 0.9,
smooth grains, T0 = 1e-9 J) with --grains grains, built once, then run for --time
simulated seconds by the event-driven engine and by the soft engine (Hertz with Tsuji's
damping for e = 0.9, no friction, the suggested time step); printed: the wall time of
each, the collisions each counted, the final temperatures, and the ratio of wall times.

peer: side by side with Smallenburg's EDMD codes (Eur. Phys. J. E 45, 22 (2022),
github.com/FSmallenburg/EDMD, a checkout in EDMD_DIR; C, built here with its own
Makefile flags): the elastic monodisperse 3D gas of N = 4 n^3 spheres (n = --cells) at
packing fractions 0.05 and 0.3, which EDMD starts from an fcc crystal.  Each of its codes
(Cell: cell lists; Single: neighbour lists, one event per sphere) is compiled with those
settings and no thermostat, and run twice, to 5 and to 5 + --collisions collisions per
sphere (Enskog's rate); its rate is the difference of collisions over the difference of
wall times, so start-up and melting are left out.  graindyn's engine runs the same N and
packing fraction as `rates` builds it, timed the same way; printed per state: each
code's collisions per second and graindyn's over the best of EDMD's, --repeats times
in turn, and the median of those ratios.
"""
import argparse
import math
import resource
import time

import numpy as np


def peak_memory():
    """Peak resident memory of the process [bytes]."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def gas(n, phi, dim, restitution=None, seed=2, temperature=1e-9, radius=5e-4):
    """An EventDriven gas in a periodic box and its volume."""
    import graindyn as gd
    from graindyn.core.state import cell_order
    from graindyn.core.walls import Periodic
    from graindyn.engines.event_driven.engine import EventDriven
    from graindyn.protocols.prepare import BoxRegion, maxwellian_velocities, \
        random_insertion

    rng = np.random.default_rng(seed)
    solid = n * (4 / 3 * math.pi * radius**3 if dim == 3 else math.pi * radius**2)
    side = (solid / phi) ** (1 / dim)
    positions, radii = random_insertion(np.full(n, radius), BoxRegion((0.0,) * dim,
                                                                      (side,) * dim),
                                        rng, dim, periodic=range(dim))
    order = cell_order(positions, 2 * radius)         # as prepare.fill orders grains
    state = gd.State.create(positions[order], radii[order], 2500.0, dim=dim)
    state.velocities[:] = maxwellian_velocities(state.masses, temperature, rng, dim)
    engine = EventDriven(state, [gd.Material(restitution=restitution)],
                         periodic=[Periodic(a, 0.0, side) for a in range(dim)],
                         gravity=(0.0, 0.0, 0.0))
    return engine, side**dim


def timed_gas(n, phi, dim, per_grain):
    """The gas of ``gas`` run 5 collisions per grain untimed, then ``per_grain`` timed
    (Enskog's rate): (collisions, wall s, events per collision)."""
    from graindyn.analysis.gas import enskog_collision_rate

    engine, volume = gas(n, phi, dim)
    rate = enskog_collision_rate(n / volume, 1e-3, 1e-9, engine.state.masses[0], phi, dim)
    engine.run(time=5 * 2 / rate)
    c0, e0 = engine.collisions, engine.events
    start = time.perf_counter()
    engine.run(time=per_grain * 2 / rate)
    wall = time.perf_counter() - start
    c = engine.collisions - c0
    return c, wall, (engine.events - e0) / c


def rates(grains, per_grain):
    print("dim phi grains collisions wall_s collisions_per_s events_per_collision "
          "peak_rss_bytes")
    for n in grains:
        for dim in (3, 2):
            for phi in (0.05, 0.3):
                c, wall, events = timed_gas(n, phi, dim, per_grain)
                print(f"{dim} {phi} {n} {c} {wall:.3f} {c / wall:.4g} {events:.2f} "
                      f"{peak_memory()}", flush=True)


def versus(n, duration):
    import graindyn as gd
    from graindyn.analysis.gas import granular_temperature

    hard, volume = gas(n, 0.05, 3, restitution=0.9)
    positions = hard.state.positions.copy()
    velocities = hard.state.velocities.copy()
    material = gd.Material(density=2500.0, youngs_modulus=6.3e10, poisson_ratio=0.23,
                           restitution=0.9)
    state = gd.State.create(positions, hard.state.radii, 2500.0, velocities=velocities)
    side = volume ** (1 / 3)
    soft = gd.Simulation(state, [material], gd.ContactModel("hertz", "tsuji", "none"),
                         periodic=[gd.core.walls.Periodic(a, 0.0, side) for a in range(3)],
                         gravity=(0.0, 0.0, 0.0))
    soft.run(steps=10)                      # compile and warm up, untimed
    hard.run(time=1e-6)
    rows = []
    for name, engine in (("event_driven", hard), ("soft", soft)):
        c0 = engine.collisions
        start = time.perf_counter()
        engine.run(time=duration)
        wall = time.perf_counter() - start
        rows.append((name, wall, engine.collisions - c0,
                     granular_temperature(engine.state)[0]))
        extra = f" dt {engine.dt:.3g} s steps {engine.step}" if name == "soft" else \
            f" events {engine.events}"
        print(f"{name}: {n} grains, {duration} s simulated in {wall:.3f} s wall, "
              f"{rows[-1][2]} collisions, final T {rows[-1][3]:.4g} J{extra}", flush=True)
    print(f"soft / event_driven wall time: {rows[1][1] / rows[0][1]:.1f}; collisions "
          f"soft / event_driven {rows[1][2] / max(rows[0][2], 1):.3f}; peak_rss_bytes "
          f"{peak_memory()}")


EDMD_SETTINGS = {"initialconfig": "1", "makesnapshots": "0", "usethermostat": "0"}


def edmd_binary(source, code, cells, phi, maxtime, build):
    """Compile EDMD's ``code`` (Cell or Single) from ``source`` into ``build`` with
    N = 4 cells^3, packing fraction ``phi``, no thermostat, one report at the end."""
    import re
    import subprocess

    text = (source / code / f"md{code}.c").read_text()
    settings = {**EDMD_SETTINGS, "N": str(4 * cells**3), "packfrac": repr(phi),
                "maxtime": repr(maxtime), "writeinterval": repr(maxtime)}
    for name, value in settings.items():
        text, count = re.subn(rf"^((?:const )?(?:int|double) {name}\s*=\s*)[^;]+;",
                              rf"\g<1>{value};", text, count=1, flags=re.M)
        if count != 1:
            raise SystemExit(f"EDMD {code}: no global {name} to set")
    folder = build / f"{code}_{cells}_{phi}_{maxtime:.6g}"
    folder.mkdir(parents=True, exist_ok=True)
    for f in (source / code).iterdir():
        if f.suffix in (".h", ".c"):
            (folder / f.name).write_text(f.read_text())
    (folder / f"md{code}.c").write_text(text)
    subprocess.run(["gcc", "-Wall", "-Ofast", "-funroll-loops", "-march=native",
                    f"md{code}.c", "-o", "md", "-lm"], cwd=folder, check=True,
                   capture_output=True)
    return folder


def edmd_run(folder):
    """Run a built EDMD code: (wall s, collisions)."""
    import subprocess

    start = time.perf_counter()
    out = subprocess.run(["./md"], cwd=folder, check=True, capture_output=True,
                         text=True).stdout
    wall = time.perf_counter() - start
    counts = [int(line.split("Collisions:")[1].split(",")[0])
              for line in out.splitlines() if "Collisions:" in line]
    return wall, counts[-1]


def peer(source, cells, per_grain, repeats):
    import pathlib
    import tempfile

    from graindyn.analysis.gas import enskog_collision_rate

    source = pathlib.Path(source)
    build = pathlib.Path(tempfile.mkdtemp(prefix="edmd_"))
    print("phi grains repeat code collisions wall_s collisions_per_s "
          "graindyn_over_best_edmd")
    for n in cells:
        grains = 4 * n**3
        for phi in (0.05, 0.3):
            # EDMD's reduced units: sigma = m = kT = 1
            rate = enskog_collision_rate(6 * phi / math.pi, 1.0, 1.0, 1.0, phi, 3)
            warm, total = 5 * 2 / rate, (5 + per_grain) * 2 / rate
            binaries = {code: [edmd_binary(source, code, n, phi, t, build)
                               for t in (warm, total)] for code in ("Cell", "Single")}
            ratios = []
            for repeat in range(repeats):
                best = 0.0
                for code, folders in binaries.items():
                    (w1, c1), (w2, c2) = (edmd_run(folder) for folder in folders)
                    best = max(best, (c2 - c1) / (w2 - w1))
                    print(f"{phi} {grains} {repeat} EDMD-{code} {c2 - c1} {w2 - w1:.3f} "
                          f"{(c2 - c1) / (w2 - w1):.4g}", flush=True)
                c, wall, _ = timed_gas(grains, phi, 3, per_grain)
                ratios.append(c / wall / best)
                print(f"{phi} {grains} {repeat} graindyn {c} {wall:.3f} {c / wall:.4g} "
                      f"{ratios[-1]:.3f}", flush=True)
            print(f"{phi} {grains} median graindyn_over_best_edmd "
                  f"{float(np.median(ratios)):.3f} of {repeats}", flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="what", required=True)
    r = sub.add_parser("rates")
    r.add_argument("--grains", type=int, nargs="+", default=[10000, 100000])
    r.add_argument("--collisions", type=float, default=20.0)
    v = sub.add_parser("versus")
    v.add_argument("--grains", type=int, default=2000)
    v.add_argument("--time", type=float, default=0.05)
    e = sub.add_parser("peer")
    e.add_argument("edmd", help="a checkout of github.com/FSmallenburg/EDMD")
    e.add_argument("--cells", type=int, nargs="+", default=[14, 29],
                   help="N = 4 n^3 spheres (14: 10 976, 29: 97 556)")
    e.add_argument("--collisions", type=float, default=20.0)
    e.add_argument("--repeats", type=int, default=1,
                   help="rounds of all codes, one after the other (the machine's "
                        "noise moves single runs by 10-20 %%)")
    args = parser.parse_args()
    if args.what == "rates":
        rates(args.grains, args.collisions)
    elif args.what == "versus":
        versus(args.grains, args.time)
    else:
        peer(args.edmd, args.cells, args.collisions, args.repeats)


if __name__ == "__main__":
    main()
