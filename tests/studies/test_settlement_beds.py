"""Settlement studies of several beds pooled into one ensemble (studies/settlement_beds.py)."""
import csv
import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from graindyn.cli import app
from graindyn.studies.settlement_beds import (error_shares, pool_beds, procedure_runs,
                                              settlement_after_jumps)

RUN = "linear_ki30_k10_h20"
SETTINGS = {"protocol.jump_tolerance": 0.005, "protocol.undone_jump": "retry"}


def _study(folder, seed, runs, overrides=None):
    """A finished study's summary.json: ``runs`` {name: (rate [m/cycle], offset at the
    last cycle [m], reference, CPU s)}; each path settles at ``rate`` a cycle over
    cycles 1-10, a procedure reporting cycles 1, 5 and 10 (jumps in between) with its
    offset reached linearly from cycle 1."""
    summary = {"overrides": {**({"run.seed": seed} if seed is not None else {}),
                             **SETTINGS, **(overrides or {})},
               "grains": 430, "mode": "fully", "estimator": "linear", "runs": {},
               "paths": {}}
    for name, (rate, offset, reference, cpu) in runs.items():
        cycles = range(1, 11) if offset is None else (1, 5, 10)
        summary["paths"][name] = [[c, rate * c + (offset or 0.0) * (c - 1) / 9,
                                   "computed"] for c in cycles]
        summary["runs"][name] = {"reference": reference, "cycles": 10, "cpu_s": cpu}
    folder.mkdir()
    (folder / "summary.json").write_text(json.dumps(summary))
    return folder


@pytest.fixture
def studies(tmp_path):
    """Bed 1 with a replica of full DEM and of the procedure, bed 2 without."""
    one = _study(tmp_path / "bed1", None, {
        "full_dem": (1e-4, None, "full_dem", 100.0),
        "full_dem_replica_1": (1.1e-4, None, "full_dem", 110.0),
        RUN: (1e-4, -2e-5, "full_dem", 30.0),
        RUN + "_replica_1": (1.1e-4, 1e-5, "full_dem_replica_1", 35.0)})
    two = _study(tmp_path / "bed2", 2, {
        "full_dem": (2e-4, None, "full_dem", 120.0),
        RUN: (2e-4, -4e-5, "full_dem", 40.0)})
    return one, two


def test_every_pair_of_every_study_is_one_sample(studies, tmp_path):
    """Three pairs (bed 1, its replica, bed 2), differences -2e-5, 1e-5 and -4e-5 m at
    cycle 10 over full DEM settling 1e-3, 1.1e-3 and 2e-3 m."""
    pooled = pool_beds(studies, tmp_path / "pooled", at=(5, 10))
    e = pooled["ensemble"]
    d = np.array([-2e-5, 1e-5, -4e-5])
    full = np.array([1e-3, 1.1e-3, 2e-3])
    assert pooled["run"] == RUN
    assert [p for p, _ in e["pairs"]] == [f"bed1/{RUN}", f"bed1/{RUN}_replica_1",
                                          f"bed2/{RUN}"]
    assert e["pairs"][1][1] == "bed1/full_dem_replica_1"
    assert e["settlement_bias"] == pytest.approx(d.mean() / full.mean())
    assert e["settlement_bias_se"] == pytest.approx(d.std(ddof=1) / math.sqrt(3)
                                                    / full.mean())
    assert e["speedup"] == pytest.approx(330.0 / 105.0)
    # at cycle 5 each procedure is 4/9 of its way to its offset
    bias_5, _ = e["bias_at"]["5"]
    assert bias_5 == pytest.approx(4 / 9 * d.mean() / (5 * full.mean() / 10))
    with open(tmp_path / "pooled" / "pooled.csv") as f:
        rows = list(csv.DictReader(f))
    assert [float(r["difference_m"]) for r in rows] == pytest.approx(list(d))
    assert (tmp_path / "pooled" / "settlement_ensemble.png").stat().st_size > 0


def test_procedure_runs_group_replicas_under_their_run(studies):
    summary = json.loads((studies[0] / "summary.json").read_text())
    assert procedure_runs(summary) == {RUN: [RUN, RUN + "_replica_1"]}


def test_studies_that_cannot_be_pooled_are_refused(studies, tmp_path):
    one, two = studies
    same = _study(tmp_path / "bed1_again", None, {"full_dem": (1e-4, None, "full_dem", 1.0),
                                                 RUN: (1e-4, 0.0, "full_dem", 1.0)})
    with pytest.raises(ValueError, match="same bed"):
        pool_beds([one, same], tmp_path / "out")
    other = _study(tmp_path / "slide", 3, {"full_dem": (1e-4, None, "full_dem", 1.0),
                                           RUN: (1e-4, 0.0, "full_dem", 1.0)},
                   {"protocol.undone_jump": "slide"})
    with pytest.raises(ValueError, match="protocol.undone_jump"):
        pool_beds([one, other], tmp_path / "out")
    with pytest.raises(ValueError, match="not a procedure run of every study"):
        pool_beds([one, two], tmp_path / "out", run="shenton_ki10_k40_h10")
    with pytest.raises(ValueError, match="no summary.json"):
        pool_beds([one, tmp_path / "nothing"], tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_the_command_prints_the_bias_along_the_cycles(studies, tmp_path):
    result = CliRunner().invoke(app, ["study", "settlement-beds", *map(str, studies),
                                      "--out", str(tmp_path / "p"), "--at", "10"])
    assert result.exit_code == 0, result.output
    assert "3 pairs from 2 studies" in result.output
    assert "cycle 10: bias -1.22 +- " in result.output
    result = CliRunner().invoke(app, ["study", "settlement-beds", str(studies[0])])
    assert result.exit_code != 0 and "at least two" in result.output


def test_the_settlement_after_a_jump_is_set_against_full_dem_s_by_lag():
    """Full DEM settles 1 mm a cycle; the procedure computes cycles 1-5 (before any
    jump: left out), jumps 5 -> 10, computes 11-14 at 0.5 mm a cycle, then jumps 14 ->
    20 and computes 21 at 2 mm: lags 1-4 after the first jump, lag 1 after the
    second."""
    full = [(c, 1e-3 * c, "computed") for c in range(0, 31)]
    path = [(c, 1e-3 * c, "computed") for c in range(1, 6)] + [(10, 0.010, "extrapolated")]
    path += [(c, 0.010 + 0.5e-3 * (c - 10), "computed") for c in range(11, 15)]
    path += [(20, 0.020, "extrapolated"), (21, 0.022, "computed")]
    sums = settlement_after_jumps(path, full, most=5)
    assert sums[1] == pytest.approx([0.5e-3 + 2e-3, 2e-3, 2])
    for lag in (2, 3, 4):
        assert sums[lag] == pytest.approx([0.5e-3, 1e-3, 1])
    assert sums[5] == [0.0, 0.0, 0]


def _log_path(cycles, a=1e-3, c=2e-3):
    """Full DEM settling as c + a ln N [m] at every cycle N in ``cycles``."""
    return [(n, c + a * math.log(n), "computed") for n in cycles]


@pytest.mark.parametrize("estimator", ["linear", "logarithmic"])
def test_a_procedure_that_follows_full_dem_has_only_the_estimator_s_share(estimator):
    """Full DEM settles as c + a ln N; a procedure computes cycles 1-30 and 41-60 on
    full DEM's path and jumps 30 -> 41 and 60 -> 100 as its estimator carries full
    DEM's last 10 cycles (k = 10, 50 Hz).  The logarithmic law follows the path
    exactly: no share at all.  Eq. 16 carries the window's mean rate a ln(30/20)/10 on
    over 11 cycles and a ln(60/50)/10 over 40 where the path gains a ln(41/30) and a
    ln(100/60): its share is that overshoot, by hand; the bed's share is zero."""
    a, period = 1e-3, 0.02
    full = _log_path(range(1, 101), a)
    settle = dict((n, s) for n, s, _ in full)
    if estimator == "linear":
        jumps = [(30, 41, a * math.log(30 / 20) * 11 / 10), (60, 100, a * math.log(60 / 50) * 4)]
    else:
        jumps = [(30, 41, a * math.log(41 / 30)), (60, 100, a * math.log(100 / 60))]
    path = [p for p in full if p[0] <= 30]
    path.append((41, settle[30] + jumps[0][2], "extrapolated"))
    path += [(n, s - settle[41] + path[-1][1], "computed") for n, s, _ in full if 41 < n <= 60]
    path.append((100, path[-1][1] + jumps[1][2], "extrapolated"))
    shares = error_shares(path, full, estimator, 10, period)
    assert shares["jumps"] == 2
    own = sum(j[2] for j in jumps) - a * (math.log(41 / 30) + math.log(100 / 60))
    assert shares["extrapolated"] == pytest.approx(own, rel=1e-9, abs=1e-15)
    assert shares["estimator"] == pytest.approx(own, rel=1e-9, abs=1e-15)
    assert abs(shares["bed"]) < 1e-15
    if estimator == "linear":
        assert own == pytest.approx(a * (math.log(1.5) * 1.1 - math.log(41 / 30)
                                         + math.log(1.2) * 4 - math.log(100 / 60)))
        assert own > 1e-4
    else:
        assert abs(own) < 1e-15


def test_a_bed_that_settles_slower_after_a_jump_has_a_bed_share():
    """Full DEM settles 1 um a cycle; the procedure jumps 30 -> 50 exactly, then its
    bed settles 0.5 um a cycle over cycles 51-60 and the next jump, 60 -> 100, carries
    that rate on: Eq. 16 on full DEM's path has no share, and the bed's is the 20 um
    the slower window cost the second jump (its 5 um over the window are no jump's)."""
    full = [(n, 1e-6 * n, "computed") for n in range(1, 101)]
    path = [p for p in full if p[0] <= 30] + [(50, 50e-6, "extrapolated")]
    path += [(n, 50e-6 + 0.5e-6 * (n - 50), "computed") for n in range(51, 61)]
    path.append((100, path[-1][1] + 0.5e-6 * 40, "extrapolated"))
    shares = error_shares(path, full, "linear", 10, 0.02)
    assert abs(shares["estimator"]) < 1e-15
    assert shares["bed"] == pytest.approx(-20e-6, rel=1e-9)
    assert shares["extrapolated"] == pytest.approx(-20e-6, rel=1e-9)


def test_a_window_full_dem_does_not_cover_is_refused():
    full = [(n, 1e-6 * n, "computed") for n in range(5, 101)]
    path = [p for p in full if p[0] <= 10] + [(20, 20e-6, "extrapolated")]
    with pytest.raises(ValueError, match="lacks cycles"):
        error_shares(path, full, "linear", 10, 0.02)
