"""Instructions and L1 data-cache misses per collision of the event-driven engine, counted
exactly by valgrind's cachegrind (wall times on a shared machine move by 10-20 % from
run to run; these counts do not).

    python benchmarks/event_driven_instructions.py [--grains 97556] [--phi 0.05]
        [--collisions 2] [--edmd EDMD_DIR]

The `rates` gas of event_driven_gas.py (3D, smooth elastic spheres, periodic box) is run
3 collisions per grain, saved, and then run under cachegrind twice from the saved
state: for --collisions per grain and for almost none; the difference, over the
difference of collisions, leaves start-up and compilation out.  Under valgrind numba
would see another processor and compile afresh (about 15 minutes); both runs therefore
set NUMBA_CPU_NAME and NUMBA_CPU_FEATURES to one AVX2 target (valgrind runs no AVX-512)
and a compile cache of their own, which a native run fills first.  --edmd: Smallenburg's
Cell code built for the same target (-march=x86-64-v3) and counted the same way, over
the collisions from 5 to 5 + --collisions per sphere of its own gas of the same N
(N = 4 n^3) and packing fraction.  Needs valgrind on the PATH.
"""
import argparse
import math
import os
import pathlib
import re
import subprocess
import sys
import tempfile

HERE = pathlib.Path(__file__).parent
TARGET = {"NUMBA_CPU_NAME": "haswell",
          "NUMBA_CPU_FEATURES": "+64bit,+avx,+avx2,+bmi,+bmi2,+cmov,+cx16,+f16c,+fma,"
                                "+fsgsbase,+lzcnt,+mmx,+movbe,+pclmul,+popcnt,+rdrnd,+sahf,"
                                "+sse,+sse2,+sse3,+sse4.1,+sse4.2,+ssse3,+xsave,+xsaveopt"}


def child(saved, n, phi, per_grain):
    """Run in a child process: build the gas (or load it from ``saved``, which skips the
    insertion) and run it per_grain collisions per grain; prints its collision count."""
    import numpy as np

    import graindyn as gd
    from graindyn.analysis.gas import enskog_collision_rate
    from graindyn.core.walls import Periodic
    from graindyn.engines.event_driven.engine import EventDriven

    if saved.exists():
        data = np.load(saved)
        side = float(data["side"])
        state = gd.State.create(data["positions"], np.full(n, 5e-4), 2500.0, dim=3)
        state.velocities[:] = data["velocities"]
        engine = EventDriven(state, [gd.Material()],
                             periodic=[Periodic(a, 0.0, side) for a in range(3)],
                             gravity=(0.0, 0.0, 0.0))
    else:
        sys.path.insert(0, str(HERE))
        from event_driven_gas import gas

        engine, volume = gas(n, phi, 3)
        side = volume ** (1 / 3)
    rate = enskog_collision_rate(n / side**3, 1e-3, 1e-9, engine.state.masses[0], phi, 3)
    engine.run(time=per_grain * 2 / rate)
    if not saved.exists():
        np.savez(saved, positions=engine.state.positions,
                 velocities=engine.state.velocities, side=side)
    print(f"collisions {engine.collisions}")


def counted(command, env, cwd=None):
    """(instructions, L1 data misses, the command's output) of one run under
    cachegrind."""
    out = tempfile.mktemp(prefix="cachegrind_")
    run = subprocess.run(["valgrind", "--tool=cachegrind", "--cache-sim=yes",
                          f"--cachegrind-out-file={out}", *command], env=env, cwd=cwd,
                         capture_output=True, text=True, check=True)
    os.unlink(out)
    text = run.stderr

    def number(key):
        return int(re.search(key + r":\s+([\d,]+)", text).group(1).replace(",", ""))

    return number("I   refs"), number("D1  misses"), run.stdout


def per_collision(short, long, short_collisions, long_collisions):
    collisions = long_collisions - short_collisions
    return ((long[0] - short[0]) / collisions, (long[1] - short[1]) / collisions,
            collisions)


def graindyn(n, phi, per_grain, env):
    folder = pathlib.Path(tempfile.mkdtemp(prefix="instructions_"))
    saved = folder / "gas.npz"

    def command(collisions):
        return [sys.executable, __file__, "--child", str(saved), "--grains", str(n),
                "--phi", str(phi), "--collisions", str(collisions)]

    subprocess.run(command(3), env=env, check=True, capture_output=True)  # compiles
    subprocess.run(command(1e-4), env=env, check=True, capture_output=True)
    runs = [counted(command(c), env) for c in (1e-4, per_grain)]
    counts = [int(re.search(r"collisions (\d+)", r[2]).group(1)) for r in runs]
    return per_collision(runs[0], runs[1], *counts)


def edmd(source, n, phi, per_grain):
    sys.path.insert(0, str(HERE))
    from event_driven_gas import edmd_binary
    from graindyn.analysis.gas import enskog_collision_rate

    cells = round((n / 4) ** (1 / 3))
    rate = enskog_collision_rate(6 * phi / math.pi, 1.0, 1.0, 1.0, phi, 3)
    build = pathlib.Path(tempfile.mkdtemp(prefix="edmd_"))
    runs = []
    for per in (5, 5 + per_grain):
        folder = edmd_binary(pathlib.Path(source), "Cell", cells, phi, per * 2 / rate,
                             build)
        subprocess.run(["gcc", "-Ofast", "-funroll-loops", "-march=x86-64-v3",
                        "mdCell.c", "-o", "md", "-lm"], cwd=folder, check=True,
                       capture_output=True)
        instructions, misses, out = counted(["./md"], os.environ, cwd=folder)
        collisions = int(out.split("Collisions:")[-1].split(",")[0])
        runs.append((instructions, misses, collisions))
    return per_collision(runs[0][:2], runs[1][:2], runs[0][2], runs[1][2])


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--grains", type=int, default=97556)
    parser.add_argument("--phi", type=float, default=0.05)
    parser.add_argument("--collisions", type=float, default=2.0)
    parser.add_argument("--edmd", help="a checkout of github.com/FSmallenburg/EDMD")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(pathlib.Path(args.child), args.grains, args.phi, args.collisions)
        return
    env = {**os.environ, **TARGET, "GRAINDYN_CACHE_DIR": str(
        pathlib.Path(tempfile.gettempdir()) / "graindyn_valgrind_cache")}
    print("code grains phi collisions instructions_per_collision "
          "l1d_misses_per_collision")
    i, m, c = graindyn(args.grains, args.phi, args.collisions, env)
    print(f"graindyn {args.grains} {args.phi} {c} {i:.0f} {m:.1f}", flush=True)
    if args.edmd:
        i, m, c = edmd(args.edmd, args.grains, args.phi, args.collisions)
        print(f"EDMD-Cell {args.grains} {args.phi} {c} {i:.0f} {m:.1f}", flush=True)


if __name__ == "__main__":
    main()
