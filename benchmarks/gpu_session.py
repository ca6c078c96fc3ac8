"""The GPU checks of one lease of a GPU machine, in one command: what the device is, the
GPU suite on the device instead of the simulator (parity with the CPU), and the speed
of the anchor bed and of an ensemble of oedometers (benchmarks/gpu_bench.py).

    python benchmarks/gpu_session.py OUT [--budget S] [--states DIR] [--only NAMES]
    python benchmarks/gpu_session.py OUT --rehearse

Each stage runs in its own process under a time limit (its own, and what is left of
``--budget`` seconds, default 480: a lease is 15 minutes, starting the machine
included), in the order below, so that what matters most comes first and a stage that
hangs costs only its own limit.  Everything goes to two files in OUT, written as each
stage ends (a stopped session still brings back what it did): session.log (every
stage's command, output and time) and session.json (one object per stage: name,
command, exit code, seconds, and the ``key value`` lines of gpu_bench).

Stages:
  device     nvidia-smi, the Python, numpy, numba and numba-cuda versions, cuda.detect()
  parity     tests/gpu/test_cudasim.py with GRAINDYN_GPU=device: CPU against GPU on
             single collisions of every law and integrator (1e-10), the neighbour
             lists, the checks, checkpoints moved between backends, ensemble members
             against the systems alone, the run and sweep commands and the silo
  bed-1e6    the anchor bed (Hertz-Mindlin, d = 1 mm, E = 1e8 Pa, dt = 2e-6 s), the
             settled 10 000-grain bed of ../shared/bench tiled 10 x 10
  ensemble   1 000 oedometers of 280 grains advanced together
  bed-1e7    the anchor bed tiled 32 x 32 (1.02e7 grains)
  bed-1e5    the anchor bed tiled 10 x 1
  sweep      the Tables 2-3 sweep (examples/oedometer_sweep.toml) with backend gpu: its
             runs advanced as one GPU ensemble, for as long as the budget lasts (its
             progress lines say how far it came; rerun with --only sweep to go on)

The settled states come from ../shared/bench (``run_all.py`` prepares them with LAMMPS,
which the GPU machine does not have): state_settle_10000.txt and state_oedo_280.txt in
``--states`` (default .devstate, a folder git ignores, carried to the machine).
Packages the machine's image lacks travel as wheels in .whl (README of the device
tool).  ``bash benchmarks/gpu_session.sh prepare`` makes both folders here;
``bash benchmarks/gpu_session.sh`` on the machine installs the wheels and calls this
script.

``--rehearse`` runs every stage here under the CUDA simulator with tiny sizes (a bed of
280 grains, 2 members, 2 steps; the parity stage as CI runs it) to check the script
itself before a lease is spent on it.
"""
import argparse
import json
import os
import pathlib
import subprocess
import sys
import time

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parent


def gpu_sweep(folder, sweep):
    """A copy of the sweep file ``sweep`` and of its base config in ``folder``, the base
    run on backend gpu; returns the copy's path."""
    folder.mkdir(parents=True, exist_ok=True)
    text = sweep.read_text()
    base = next(line.split("=", 1)[1].strip().strip('"') for line in text.splitlines()
                if line.startswith("base"))
    config = (sweep.parent / base).read_text()
    assert "\n[run]\n" in config, "the base config has no [run] table"
    (folder / base).write_text(config.replace("\n[run]\n", '\n[run]\nbackend = "gpu"\n', 1))
    copy = folder / sweep.name
    copy.write_text(text)
    return copy


def stages(states, rehearse, scratch):
    """(name, argv, environment changes, own limit [s]) of every stage, in order."""
    py = sys.executable
    bench = str(HERE / "gpu_bench.py")
    settle = str(states / "state_settle_10000.txt")
    oedo = str(states / "state_oedo_280.txt")
    device = {} if rehearse else {"GRAINDYN_GPU": "device"}
    info = ("import sys, numpy, numba; print('python', sys.version.split()[0]); "
            "print('numpy', numpy.__version__); print('numba', numba.__version__); "
            "import numba_cuda; print('numba-cuda', numba_cuda.__version__); "
            "from numba import cuda; cuda.detect()")
    if rehearse:
        beds = [("bed-1e6", [py, bench, "bed", oedo, "0.008", "1", "1", "1", "2"]),
                ("ensemble", [py, bench, "ensemble", oedo, "0.004", "2", "1", "2"]),
                ("bed-1e7", [py, bench, "bed", oedo, "0.008", "2", "1", "1", "2"]),
                ("bed-1e5", [py, bench, "bed", oedo, "0.008", "1", "1", "1", "2"])]
    else:
        beds = [("bed-1e6", [py, bench, "bed", settle, "0.024", "10", "10", "200", "1000"]),
                ("ensemble", [py, bench, "ensemble", oedo, "0.004", "1000", "1000", "5000"]),
                ("bed-1e7", [py, bench, "bed", settle, "0.024", "32", "32", "100", "300"]),
                ("bed-1e5", [py, bench, "bed", settle, "0.024", "10", "1", "200", "2000"])]
    limits = {"bed-1e6": 90, "ensemble": 120, "bed-1e7": 180, "bed-1e5": 60}
    sweep = [py, "-m", "graindyn", "sweep",
             str(gpu_sweep(scratch / "sweep", ROOT / "examples" / "oedometer_sweep.toml")),
             "--out", str(scratch / "sweep" / "out")] + (["--dry-run"] if rehearse else [])
    return ([("device", ["nvidia-smi"], {}, 20),
             ("versions", [py, "-c", info], {}, 60),
             ("parity", [py, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                         str(ROOT / "tests" / "gpu" / "test_cudasim.py")], device, 240)]
            + [(name, argv, {}, limits[name]) for name, argv in beds]
            + [("sweep", sweep, {}, 3600)])


def values(output):
    """The ``key value`` pairs of gpu_bench's lines (numbers where they read as one)."""
    found = {}
    for line in output.splitlines():
        words = line.split()
        for key, value in zip(words[::2], words[1::2]):
            if key.replace("_", "").isalpha():
                try:
                    found[key] = float(value)
                except ValueError:
                    found[key] = value
    return found


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", type=pathlib.Path)
    parser.add_argument("--budget", type=float, default=480.0,
                        help="seconds for all stages together")
    parser.add_argument("--states", type=pathlib.Path, default=ROOT / ".devstate")
    parser.add_argument("--scratch", type=pathlib.Path, default=pathlib.Path("/tmp/gpu_session"),
                        help="folder of the sweep's files and runs")
    parser.add_argument("--only", default=None, help="comma-separated stage names")
    parser.add_argument("--rehearse", action="store_true",
                        help="every stage under the CUDA simulator, tiny sizes")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    log = args.out / "session.log"
    record = args.out / "session.json"
    chosen = set(args.only.split(",")) if args.only else None
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT / "src"),
                                                      str(HERE),
                                                      env.get("PYTHONPATH")]))
    if args.rehearse:
        env["NUMBA_ENABLE_CUDASIM"] = "1"
    start = time.monotonic()
    done = []
    for name, command, changes, limit in stages(args.states, args.rehearse, args.scratch):
        if chosen is not None and name not in chosen:
            continue
        left = args.budget - (time.monotonic() - start)
        if left < 10:
            done.append({"stage": name, "skipped": f"{left:.0f} s of the budget left"})
            record.write_text(json.dumps(done, indent=1))
            continue
        timeout = min(limit, left)
        t0 = time.monotonic()
        try:
            run = subprocess.run(command, env=dict(env, **changes), cwd=ROOT, text=True,
                                 stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                 timeout=timeout)
            output, code = run.stdout, run.returncode
        except subprocess.TimeoutExpired as stopped:
            output = stopped.stdout or ""
            if isinstance(output, bytes):
                output = output.decode(errors="replace")
            code = f"stopped after {timeout:.0f} s"
        except FileNotFoundError as missing:
            output, code = str(missing), "not found"
        seconds = time.monotonic() - t0
        entry = {"stage": name, "command": " ".join(command), "exit": code,
                 "seconds": round(seconds, 1)}
        if name.startswith(("bed", "ensemble")):
            entry.update(values(output))
        done.append(entry)
        with log.open("a") as f:
            f.write(f"=== {name} ({seconds:.1f} s, exit {code}): {' '.join(command)}\n"
                    f"{output}\n")
        record.write_text(json.dumps(done, indent=1))
        print(f"{name}: exit {code}, {seconds:.1f} s", flush=True)


if __name__ == "__main__":
    main()
