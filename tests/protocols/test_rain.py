"""Gentle filling (protocols.phases.Rain): grains rained in one by one from a fixed
height at a controlled rate, in 3D and 2D, through the deposition protocol."""
import copy

import numpy as np
import pytest

import graindyn as gd
from graindyn.config import validate
from graindyn.runner import execute

from runner.conftest import SMALL      # the 120-grain deposition of the run tests

MU_WALL = gd.Material().friction_sliding     # grains and walls keep the default friction


@pytest.mark.parametrize("dim", [3, 2])
def test_rained_grains_land_one_by_one_and_the_floor_carries_no_more_than_their_weight(
        dim, tmp_path):
    """Every grain is rained in (none left in the reservoir, all inside the container),
    the rain lasts N / rate (the grains are released at that rate), and the settled
    floor carries the weight less what the side walls hold up by friction, which
    Coulomb bounds: |F_floor - W| <= mu sum |F_side, horizontal| (the walls' friction,
    locked in as the last grains land, can point either way), with 1 % for the
    motion left at the threshold."""
    data = copy.deepcopy(SMALL)
    data["protocol"] = {"filling": "rain", "rain_rate": 250.0, "rain_height": 0.012,
                        "max_time": 1.0, "threshold": 1e-5}
    data["output"] = {"series_every": 0.01, "figures": False}
    if dim == 2:            # disks 1 mm thick: areal densities [kg/m^2]
        data["run"] = {**data["run"], "dim": 2, "gravity": [0.0, -9.81, 0.0]}
        data["materials"] = [{**m, "density": m.get("density", 2650.0) * 1e-3}
                             for m in data["materials"]]
        data["walls"]["container"] = {"kind": "box", "lo": [0, 0], "hi": [12e-3, 30e-3]}
    config = validate(data)
    results = execute(config, tmp_path / "run", show_progress=False, echo=lambda *a: None)
    assert results["reached"]
    ratio = results["apparent_weight_ratio"]
    from graindyn.output import checkpoint
    arrays, _, _, _ = checkpoint.latest(tmp_path / "run" / "checkpoints")
    force = arrays["walls/force"]                 # of the grains on each wall [N]
    up = dim - 1
    floor = int(np.argmax(np.abs(force[:, up])))
    sides = np.arange(len(force)) != floor
    held = MU_WALL * np.abs(force[sides, :up]).sum() / results["total_weight_N"]
    assert held < 1.0        # not void: a floor carrying nothing, or twice W, fails
    assert abs(ratio - 1.0) <= held + 0.01, (ratio, held)
    log = (tmp_path / "run" / "run.log").read_text()
    assert "phase rain ended" in log
    rain_end = float(log.split("phase rain ended at t = ")[1].split(" s")[0])
    n = config.grains.count
    assert rain_end == pytest.approx(n / 250.0, rel=0.1)
    assert not arrays["grains/fixed"].any()
    top = arrays["grains/positions"][:, dim - 1] + arrays["grains/radii"]
    assert np.all(top < 0.012 + 1e-9)
