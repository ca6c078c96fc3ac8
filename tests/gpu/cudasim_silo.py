"""Run by tests/gpu/test_cudasim.py under NUMBA_ENABLE_CUDASIM=1: a sweep of two tiny
silos made from examples/silo.toml (protocols/silo.py) with backend gpu, which
sweep.run runs as one GPU ensemble (engines/soft/gpu/batch.py), then the same two runs
on backend cpu, one after the other; prints one JSON line.

Each silo holds 16 disks of 4.9-5.1 mm in a silo 6 d_ave wide, under g = 500 m/s^2 (a
disk then leaves through the hole in about a hundred steps), for 0.5 ms of settling and
4.5 ms of discharge (144 steps):

  reference       the example's hole, 3.5 d_ave: disks flow out and are re-injected
                  above the packing (Engine.relocate) at the checks, every 0.25 t0;
  hole=0.00491    a hole narrower than all but the smallest disks: no disk leaves,
                  the silo is found jammed after c t0 (c = 1.05; every speed below
                  v0/c), which ends the first avalanche, and a tap (every wall of the
                  silo moving as a sinusoid for half a period, then put back where it
                  was) starts the second, unfinished when the discharge ends.
"""
import json
import pathlib
import sys

import numpy as np

from graindyn import runner, sweep
from graindyn.engines.soft import loop
from graindyn.engines.soft.gpu import engine as device
from graindyn.output import checkpoint


def relative_difference(a, b):
    """The largest |a - b| over the largest |a| or |b| (0 when both are zero: the wall
    forces of a silo whose disks are all in the air during a tap)."""
    scale = max(np.abs(a).max(), np.abs(b).max())
    return float(np.abs(a - b).max() / scale) if scale > 0 else 0.0


EXAMPLE = pathlib.Path(__file__).resolve().parents[2] / "examples" / "silo.toml"
SWEEP = f"""
base = "{EXAMPLE}"
seeds = [1]

[overrides]
"run.backend" = "gpu"
"run.gravity" = [0.0, -500.0, 0.0]
"grains.count" = 16
"grains.diameter.min" = 0.0049
"grains.diameter.max" = 0.0051
"walls.container.hi" = [0.03, 0.1]
"engine.dt" = 3.5e-5
"engine.skin" = 3e-3
"protocol.lattice_speed" = 0.0
"protocol.max_time" = 5e-4
"protocol.threshold" = 1e-3
"protocol.exit_depth" = 0.1
"protocol.reinject_height" = 1.0
"protocol.check_every" = 0.25
"protocol.jam_factor" = 1.05
"protocol.tap_frequency" = 1000.0
"protocol.tap_amplitude" = 1e-4
"protocol.avalanches" = 1
"protocol.jam_pictures" = 0
"protocol.discharge_time" = 4.5e-3
"output.series_every" = 1e-3
"output.figures" = false

[[vary]]
parameter = "protocol.hole"
values = [0.00491]
"""
# the arrays of the final checkpoints compared between the backends
COMPARED = ("grains/positions", "grains/velocities", "grains/angular_velocities",
            "walls/offset", "walls/force")


class Counted(device.DeviceEnsemble):
    """A DeviceEnsemble that records how many members it was built with."""

    sizes = []

    def __init__(self, sims):
        super().__init__(sims)
        self.sizes.append(len(self.sims))


def main(folder):
    folder = pathlib.Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "silo_sweep.toml").write_text(SWEEP)
    swept = sweep.Sweep.load(folder / "silo_sweep.toml")
    lines = []
    device.DeviceEnsemble = Counted          # gpu.batch builds its ensembles from here
    report = sweep.run(swept, folder / "gpu", echo=lines.append)
    out = {"log": lines, "exit_code": report.exit_code, "ensembles": Counted.sizes,
           "summary": sorted(p.name for p in report.paths), "runs": {}}
    for point in swept.runs:
        config = point.config.model_copy(deep=True)
        config.run.backend = "cpu"
        runner.execute(config, folder / "cpu" / point.name, show_progress=False,
                       echo=lambda *args: None)
        results = [json.loads((folder / backend / point.name / "results.json").read_text())
                   for backend in ("cpu", "gpu")]
        ends = [checkpoint.latest(folder / backend / point.name / "checkpoints")[0]
                for backend in ("cpu", "gpu")]
        differ = {name: relative_difference(ends[0][name], ends[1][name])
                  for name in COMPARED}
        out["runs"][point.name] = {
            "steps": [int(end["loop/counters"][loop.STEP]) for end in ends],
            "differ": differ,
            **{key: [r[key] for r in results]
               for key in ("exited", "avalanches", "unfinished", "time_s")}}
    print(json.dumps(out))


if __name__ == "__main__":
    main(sys.argv[1])
