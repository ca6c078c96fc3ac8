"""Cyclic loading through a rigid plate (protocols/cyclic.py, Karrech et al.): the plate
carries the haversine stress it is given, the bed compacts cycle after cycle, and every
grain's residual displacement is written at each cycle end."""
import copy
import json
import math

import numpy as np
import pytest
import tomli_w

from graindyn.config import ConfigError, validate
from graindyn.output import checkpoint
from graindyn.output.rundir import Series
from graindyn.protocols.cyclic import load_residuals
from graindyn.runner import execute

from cli_runs import cli, stop_when_logged

RADIUS = 2.5e-3
SMALL = {
    "run": {"name": "small_cyclic", "seed": 3},
    "grains": {"count": 100, "material": "sand",
               "diameter": {"min": 0.85e-3, "max": 1.15e-3}},
    "materials": [{"name": "sand", "youngs_modulus": 1e8, "poisson_ratio": 0.25,
                   "restitution": 0.5, "friction_sliding": 0.4, "tangential_damping": 1.0}],
    "contact": {"normal": "hertz", "damping": "tsuji", "tangential": "mindlin"},
    "walls": {"material": "sand",
              "container": {"kind": "cylinder", "radius": RADIUS, "height": 12e-3}},
    "protocol": {"kind": "cyclic", "packing_fraction": 0.05, "threshold": 1e-5,
                 "max_time": 0.3, "stress_amplitude": 2e3, "frequency": 50.0, "cycles": 4},
    "output": {"series_every": 2e-4, "figures": True},
}


@pytest.fixture(scope="module")
def cyclic(tmp_path_factory):
    out = tmp_path_factory.mktemp("cyclic") / "run"
    return out, execute(validate(SMALL), out, show_progress=False, echo=lambda *a: None)


def test_the_plate_carries_the_haversine_it_is_given(cyclic):
    """Each cycle of T = 1/f ends at t0 + n T; the plate stress peaks at mid-cycle at the
    static stress plus Delta sigma plus the plate's weight over the area (the load is
    slow against the bed's response, so the bed pushes back what the plate is pushed
    with), and it is back near its least at the cycle's end."""
    out, results = cyclic
    rows = results["cycles"]
    assert [r["cycle"] for r in rows] == [1, 2, 3, 4]
    period = 1 / 50.0
    t0 = rows[0]["time_s"] - period
    for r in rows:
        assert r["time_s"] == pytest.approx(t0 + r["cycle"] * period, abs=1e-5)
    series = Series(out / "series.csv").read()
    t = series["time [s]"]
    area = math.pi * RADIUS**2
    stress = series["force_plate [N]"] / area
    weight = results["deposition"]["total_weight_N"] / area      # plate of the sample's mass
    for n in range(4):
        cycle = (t > t0 + n * period) & (t <= t0 + (n + 1) * period)
        peak = np.argmax(stress[cycle])
        assert stress[cycle][peak] == pytest.approx(2e3 + weight, rel=0.05)
        assert t[cycle][peak] - t0 - n * period == pytest.approx(period / 2, abs=period / 10)
        assert rows[n]["sigma_plate_Pa"] < 0.1 * 2e3


def test_the_bed_compacts_and_residuals_are_written(cyclic):
    out, results = cyclic
    settlement = [r["settlement_m"] for r in results["cycles"]]
    assert 0 < settlement[0] < settlement[-1] < 1e-3
    residual = load_residuals(out)
    assert residual.shape == (4, 100, 3)
    assert np.mean(residual[-1, :, 2]) < 0                        # the grains went down
    assert np.mean(np.linalg.norm(residual[-1], axis=1)) == pytest.approx(
        results["cycles"][-1]["mean_residual_m"])
    assert (out / "cycles.csv").read_text().count("\n") == 5
    assert (out / "figures" / "cyclic.png").stat().st_size > 10_000


@pytest.mark.parametrize("change, message", [
    (lambda c: c["protocol"].update(plate_material="brass"), "plate_material"),
    (lambda c: c["protocol"].update(stress_amplitude=0.0), "stress_amplitude"),
    (lambda c: c["protocol"].update(plate_mass=-1.0), "plate_mass"),
    (lambda c: c["protocol"].update(smoothing=-1.0), "smoothing"),
    (lambda c: c["protocol"].update(extrapolated_growth=0.5), "extrapolated_growth"),
    (lambda c: c["protocol"].update(restart_cycles=-1), "restart_cycles"),
    (lambda c: c["protocol"].update(final_cycles=-1), "final_cycles"),
    (lambda c: c["protocol"].update(extrapolation="linear", cycles=10, initial_cycles=5,
                                    final_cycles=5), "no cycle to extrapolate"),
    (lambda c: c["protocol"].update(relaxation="frictionless"), "relaxation"),
    (lambda c: c["protocol"].update(fit_time="wall"), "fit_time"),
    (lambda c: c["protocol"].update(smoothing_fit="median"), "smoothing_fit"),
    (lambda c: c["walls"].update(container={"kind": "box", "lo": [0, 0, 0],
                                            "hi": [5e-3, 5e-3, 1e-2],
                                            "open_top": False}), "open-top box"),
])
def test_bad_cyclic_configs_are_refused(change, message):
    data = copy.deepcopy(SMALL)
    change(data)
    with pytest.raises(ConfigError, match=message):
        validate(data)


def test_interrupted_cyclic_run_resumes_to_the_same_numbers(cyclic, tmp_path):
    """SIGTERM in the middle of the cycles, then --resume: the same cycle rows and
    the same residual displacements as the uninterrupted run, none lost or twice."""
    finished, results = cyclic
    (tmp_path / "run.toml").write_text(tomli_w.dumps(SMALL))
    run = tmp_path / "run"
    stop_when_logged(cli("run", tmp_path / "run.toml", "--out", run), run / "run.log",
                     "cycle 1:")
    _, meta, _, _ = checkpoint.read(run / "checkpoints" / "checkpoint.h5")
    assert 1 <= len(meta["protocol"]["states"]["cycles"]["rows"]) < 4
    proc = cli("run", "--resume", run)
    out, _ = proc.communicate(timeout=900)
    assert proc.returncode == 0, out
    resumed = json.loads((run / "results.json").read_text())
    assert resumed["cycles"] == json.loads((finished / "results.json").read_text())["cycles"]
    np.testing.assert_array_equal(load_residuals(run), load_residuals(finished))


@pytest.fixture(scope="module")
def procedure(tmp_path_factory):
    """Run the procedure (k_i = 2, k = 3, h = 3, 8 cycles) with extra protocol
    settings: (run directory, results), each run made once."""
    made = {}

    def run(**settings):
        key = tuple(sorted(settings.items()))
        if key not in made:
            made[key] = make(**settings)
        return made[key]

    def make(**settings):
        data = copy.deepcopy(SMALL)
        data["protocol"].update({"cycles": 8, "extrapolation": "shenton",
                                 "initial_cycles": 2, "computed_cycles": 3,
                                 "extrapolated_cycles": 3, **settings})
        data["output"]["figures"] = False
        out = tmp_path_factory.mktemp("procedure") / "run"
        return out, execute(validate(data), out, show_progress=False, echo=lambda *a: None)
    return run


def test_the_procedure_extrapolates_relaxes_and_goes_on(procedure):
    """extrapolation = shenton, k_i = 2, k = 3, h = 3, 8 cycles: cycles 1-5 computed,
    cycles 6-8 extrapolated from the records of cycles 2-5, then relaxed: the
    relaxation removes the overlaps the extrapolation made (to below 1e-3 of a radius)
    and the residuals of the computed cycles and of the extrapolation's end are
    written."""
    from graindyn.protocols.cyclic import residual_cycles

    out, results = procedure()
    assert [r["cycle"] for r in results["cycles"]] == [1, 2, 3, 4, 5]
    (jump,) = results["extrapolations"]
    assert (jump["from_cycle"], jump["to_cycle"], jump["estimator"]) == (5, 8, "shenton")
    assert jump["largest_overlap_after"] < 1e-3 < jump["largest_overlap_before"]
    assert jump["functional_after_J"] < jump["functional_before_J"]
    assert results["settlement_m"] == jump["settlement_m"]
    assert residual_cycles(out) == [1, 2, 3, 4, 5, 8]


def test_the_logarithmic_law_moves_the_plate_as_fitted_on_the_loading_clock(procedure):
    """extrapolation = logarithmic, k_i = 2, k = 3, h = 3: the plate's descent rate at
    the jump's end (cycle 7 to 8) is a ln(8 / 7), a fitted as c + a ln t to the plate's
    heights at the ends of cycles 2-5 (t = 2T..5T), by hand here."""
    _, results = procedure(extrapolation="logarithmic")
    (jump,) = results["extrapolations"]
    assert (jump["from_cycle"], jump["to_cycle"], jump["estimator"]) == (5, 8, "logarithmic")
    rows = {r["cycle"]: r["plate_height_m"] for r in results["cycles"]}
    x = np.log(np.arange(2, 6) / 50.0)
    y = np.array([rows[c] for c in range(2, 6)])
    a = np.sum((x - x.mean()) * (y - y.mean())) / np.sum((x - x.mean()) ** 2)
    assert a < 0.0
    assert jump["extrapolated_rate_m_per_cycle"] == pytest.approx(-a * math.log(8 / 7),
                                                                  rel=1e-9)


def test_the_overlaps_before_and_after_each_relaxation_are_kept_and_drawn(procedure):
    """relaxations/to_cycle_000008.npz holds every contact's relative overlap in the
    extrapolated configuration and after its relaxation, whose largest and median
    values are the jump's record; relaxation_figure draws them (Karrech Fig. 9)."""
    from graindyn.protocols.cyclic import load_overlaps, relaxation_figure

    out, results = procedure()
    (jump,) = results["extrapolations"]
    overlaps = load_overlaps(out)
    assert list(overlaps) == [8]
    before, after = overlaps[8]
    assert before.size == jump["contacts_before"] and after.size == jump["contacts_after"]
    assert before.max() == jump["largest_overlap_before"]
    assert after.max() == jump["largest_overlap_after"]
    assert np.median(after) == pytest.approx(jump["median_overlap_after"])
    assert np.median(after) < np.median(before)
    fig = relaxation_figure(out, "small")
    assert len(fig.axes) == 1 and len(fig.axes[0].patches) == 2


def test_h_grows_from_round_to_round(procedure):
    """extrapolated_growth = 2 with k_i = 2, k = 3, h = 1 over 12 cycles: cycles 1-5
    computed, 6 extrapolated (h = 1), 7-9 computed, 10-11 extrapolated (h = 2), 12
    computed; h = 4 would overshoot the last cycle, so a third round is not made."""
    _, results = procedure(cycles=12, extrapolated_cycles=1, extrapolated_growth=2.0)
    jumps = [(j["from_cycle"], j["to_cycle"]) for j in results["extrapolations"]]
    assert jumps == [(5, 6), (9, 11)]
    assert [r["cycle"] for r in results["cycles"]] == [1, 2, 3, 4, 5, 7, 8, 9, 12]


def test_the_window_opens_restart_cycles_after_a_jump(procedure):
    """restart_cycles = 1 with k_i = 2, k = 3, h = 1 over 12 cycles: cycles 1-5
    computed, 6 extrapolated; cycle 7 computed, its settling after the jump left out:
    the next window opens at its end and holds the k = 3 increments of cycles 8-10;
    11 extrapolated, and 12 computed."""
    _, results = procedure(cycles=12, extrapolated_cycles=1, restart_cycles=1)
    jumps = [(j["from_cycle"], j["to_cycle"]) for j in results["extrapolations"]]
    assert jumps == [(5, 6), (10, 11)]
    assert [r["cycle"] for r in results["cycles"]] == [1, 2, 3, 4, 5, 7, 8, 9, 10, 12]


def test_final_cycles_end_the_procedure_on_computed_cycles(procedure):
    """final_cycles = 2 with k_i = 2, k = 3, h = 3 over 8 cycles: cycles 1-5 computed;
    the jump, cut so as to leave 2 cycles, goes to cycle 6, and cycles 7-8 are
    computed from there (against the jump to cycle 8 that ends the run without it)."""
    _, results = procedure(final_cycles=2)
    jumps = [(j["from_cycle"], j["to_cycle"]) for j in results["extrapolations"]]
    assert jumps == [(5, 6)]
    assert [r["cycle"] for r in results["cycles"]] == [1, 2, 3, 4, 5, 7, 8]


def test_the_window_clock_is_the_fit_s_time(procedure):
    """fit_time = "window": the same computed cycles to the bit, then an extrapolation
    on the window's own clock, which differs from the loading clock's, relaxed (its
    overlaps removed to below 1e-3 of a radius; whether L-BFGS also reports the force
    tolerance reached after its thousands of iterations differs from one processor's
    rounding to another's)."""
    _, loading = procedure()
    _, window = procedure(fit_time="window")
    assert window["cycles"] == loading["cycles"]
    (a,), (b,) = loading["extrapolations"], window["extrapolations"]
    assert (b["from_cycle"], b["to_cycle"]) == (5, 8)
    assert b["largest_overlap_after"] < 1e-3 < b["largest_overlap_before"]
    assert b["settlement_m"] != a["settlement_m"]


def test_smoothed_increments_overlap_the_grains_less(procedure):
    """The same procedure with the extrapolated increments averaged over three radii
    (smoothing) and the contacts kept: the same computed cycles to the bit, then an
    extrapolation that drives the grains less into each other than each grain's own
    trend does, relaxed as well."""
    _, plain = procedure()
    _, smooth = procedure(smoothing=3.0, keep_contacts=True)
    assert smooth["cycles"] == plain["cycles"]
    (a,), (b,) = plain["extrapolations"], smooth["extrapolations"]
    assert b["largest_overlap_before"] < a["largest_overlap_before"]
    assert b["largest_overlap_after"] < 1e-3


def test_the_walls_keep_their_overlaps_with_excess_walls(procedure):
    """relaxation = "excess_walls" against "excess" on the same jump (the computed
    cycles are the same to the bit): the extrapolated bed is the same, but the
    grain-wall contacts (the floor, the side wall and the plate, the plate against
    where it was before the jump) enter the functional only with the overlap beyond
    what they had, so it starts lower, converges, and leaves the contacts more loaded
    (the excess relaxation empties the grain-wall contacts); the tolerance is the
    settlement study's."""
    study = dict(smoothing=3.0, keep_contacts=True, relaxation_tolerance=1e-3)
    _, pairs = procedure(relaxation="excess", **study)
    _, walls = procedure(relaxation="excess_walls", **study)
    assert walls["cycles"][:5] == pairs["cycles"][:5]
    (a,), (b,) = pairs["extrapolations"], walls["extrapolations"]
    assert b["contacts_before"] == a["contacts_before"]
    assert b["largest_overlap_before"] == a["largest_overlap_before"]
    assert 0.0 <= b["functional_before_J"] < a["functional_before_J"]
    assert a["relaxed"] and b["relaxed"]
    assert b["largest_overlap_after"] < 0.1 * b["largest_overlap_before"]
    assert b["median_overlap_after"] > a["median_overlap_after"]


@pytest.mark.parametrize("fit", ["mean", "linear"])
def test_the_procedure_runs_on_the_quarter_model(tmp_path, fit):
    """The quarter of a cylinder (symmetry planes x = 0, y = 0) through the procedure
    with smoothing (either fit), the excess relaxation and kept contacts: the
    relaxation converges and every grain ends on its side of both planes."""
    data = copy.deepcopy(SMALL)
    data["walls"]["container"]["radius"] = 2 * RADIUS
    data["walls"]["symmetry"] = [{"axis": "x"}, {"axis": "y"}]
    data["protocol"].update({"cycles": 6, "extrapolation": "shenton", "initial_cycles": 2,
                             "computed_cycles": 2, "extrapolated_cycles": 2,
                             "smoothing": 3.0, "smoothing_fit": fit,
                             "relaxation": "excess", "keep_contacts": True})
    data["output"]["figures"] = False
    out = tmp_path / "run"
    results = execute(validate(data), out, show_progress=False, echo=lambda *a: None)
    (jump,) = results["extrapolations"]
    assert (jump["from_cycle"], jump["to_cycle"]) == (4, 6)
    assert jump["relaxed"] and jump["largest_overlap_after"] < 1e-2
    arrays, _, _, _ = checkpoint.read(out / "checkpoints" / checkpoint.LATEST)
    assert np.all(arrays["grains/positions"][:, :2] > 0.0)


def test_a_jump_beyond_its_tolerance_is_undone_and_the_bed_computed_on(procedure):
    """jump_tolerance = 1e-12 (no jump can pass) with k_i = 2, k = 3, h = 3 over 12
    cycles, final_cycles = 3: cycles 1-5 computed, the jump 5 -> 8 checked on cycles
    9-11 and undone (the bed back at cycle 5, the clock on by the 3 cycles spent), 6-8
    computed, the jump 8 -> 9 (cut to leave 3 cycles) checked on 10-12 and undone,
    9-12 computed: every cycle computed once in the end, both jumps listed as rejected
    with their estimates, no file of an undone cycle or jump left behind."""
    from graindyn.protocols.cyclic import residual_cycles

    out, results = procedure(cycles=12, jump_tolerance=1e-12, final_cycles=3)
    assert [r["cycle"] for r in results["cycles"]] == list(range(1, 13))
    assert results["extrapolations"] == []
    rejected = [(j["from_cycle"], j["to_cycle"], j["checked_at_cycle"])
                for j in results["rejected_extrapolations"]]
    assert rejected == [(5, 8, 11), (8, 9, 12)]
    assert all(j["estimated_error"] > 1e-12 for j in results["rejected_extrapolations"])
    assert [j["next_h"] for j in results["rejected_extrapolations"]] == [1, 1]  # 3/5, 1/5
    period = 1 / 50.0
    t0 = results["cycles"][0]["time_s"] - period
    times = [r["time_s"] - t0 for r in results["cycles"]]
    assert times[:5] == pytest.approx([period * c for c in range(1, 6)], abs=1e-5)
    assert times[5:8] == pytest.approx([period * c for c in range(9, 12)], abs=1e-5)
    assert times[8:] == pytest.approx([period * c for c in range(15, 19)], abs=1e-5)
    assert residual_cycles(out) == list(range(1, 13))
    assert not list((out / "relaxations").glob("*.npz"))
    assert not (out / "procedure" / "before_jump.npz").exists()


def test_an_undone_jump_is_retried_at_once_from_the_same_window(procedure):
    """undone_jump = "retry" with jump_tolerance = 1e-12 (no jump can pass), k_i = 2,
    k = 3, h = 3 over 12 cycles, final_cycles = 3: cycles 1-5 computed, the jump 5 -> 8
    checked on cycles 9-11 and undone, and at once the jump 5 -> 6 (h = 3/5 rounded
    to 1) from the same window of cycles 2-5, checked on 7-9 and undone; h = 1 cannot
    shrink, so the window slides on: 6-8 computed, the jump 8 -> 9 checked on 10-12
    and undone, 9-12 computed.  Every cycle computed once in the end, on the clock of
    the cycles spent (none by a jump)."""
    out, results = procedure(cycles=12, jump_tolerance=1e-12, final_cycles=3,
                             undone_jump="retry")
    assert [r["cycle"] for r in results["cycles"]] == list(range(1, 13))
    assert results["extrapolations"] == []
    rejected = [(j["from_cycle"], j["to_cycle"], j["checked_at_cycle"])
                for j in results["rejected_extrapolations"]]
    assert rejected == [(5, 8, 11), (5, 6, 9), (8, 9, 12)]
    period = 1 / 50.0
    t0 = results["cycles"][0]["time_s"] - period
    times = [r["time_s"] - t0 for r in results["cycles"]]
    spent = list(range(1, 6)) + list(range(12, 15)) + list(range(18, 22))
    assert times == pytest.approx([period * c for c in spent], abs=1e-5)
    log = (out / "run.log").read_text()
    assert "retried at once with h = 1" in log and "the window slides on" in log


def test_a_jump_within_its_tolerance_is_kept_with_its_estimate(procedure):
    """jump_tolerance = 1e9 (every jump passes), k_i = 2, k = 3, h = 3 growing twofold
    over 12 cycles, final_cycles = 3: the jump 5 -> 8 of the procedure without the
    check (cycles 9-11 its window, no room for another), the same cycles to the bit,
    the next h grown by extrapolated_growth (the controller's own factor is far
    larger), the jump with the
    rate it extrapolated, the rate measured after it and the estimated error
    h |r_after - r_jump| / 2 over the settlement at its end."""
    _, checked = procedure(cycles=12, jump_tolerance=1e9, final_cycles=3,
                           extrapolated_growth=2.0)
    _, plain = procedure(cycles=12, final_cycles=3, extrapolated_growth=2.0)
    assert checked["cycles"] == plain["cycles"]
    assert [(j["from_cycle"], j["to_cycle"]) for j in checked["extrapolations"]] == \
        [(j["from_cycle"], j["to_cycle"]) for j in plain["extrapolations"]] == [(5, 8)]
    assert checked["rejected_extrapolations"] == []
    for j in checked["extrapolations"]:
        h = j["to_cycle"] - j["from_cycle"]
        assert j["estimated_error"] == pytest.approx(
            h * abs(j["measured_rate_m_per_cycle"] - j["extrapolated_rate_m_per_cycle"])
            / (2 * j["settlement_m"]))
        assert j["extrapolated_rate_m_per_cycle"] > 0
        assert j["next_h"] == 2 * h         # within the tolerance: grown by at most 2


def test_a_corrected_jump_is_kept_and_moved_on_by_half_its_rate_error(procedure):
    """jump_correction = "trapezoidal" with jump_tolerance = 1e-12 (every jump beyond
    it), the linear estimator, k_i = 2, k = 3, h = 3 over 12 cycles, final_cycles = 3:
    the jump 5 -> 8 is kept, not undone; once cycles 9-11 are computed the plate is
    moved on by h (r_after - r_jump) / 2 (Heun's correction of the forward jump) and
    the grains relaxed, cycle 11's settlement is the corrected one, and the next h is
    cut by the controller's largest factor (the error is far beyond the tolerance)."""
    out, results = procedure(cycles=12, jump_tolerance=1e-12, final_cycles=3,
                             extrapolation="linear", jump_correction="trapezoidal")
    assert [r["cycle"] for r in results["cycles"]] == [1, 2, 3, 4, 5, 9, 10, 11, 12]
    assert results["rejected_extrapolations"] == []
    (jump,) = results["extrapolations"]
    assert (jump["from_cycle"], jump["to_cycle"], jump["checked_at_cycle"]) == (5, 8, 11)
    assert jump["correction_m"] == pytest.approx(
        1.5 * (jump["measured_rate_m_per_cycle"] - jump["extrapolated_rate_m_per_cycle"]),
        rel=1e-9)
    assert jump["correction_m"] != 0.0
    assert jump["correction_relaxation_iterations"] > 0
    assert jump["correction_largest_overlap_after"] < 1e-3
    assert jump["next_h"] == 1                              # 3 x 0.2, rounded
    rows = {r["cycle"]: r for r in results["cycles"]}
    assert rows[11]["settlement_m"] == pytest.approx(rows[11]["plate_height_m"] * -1.0
                                                     + rows[1]["plate_height_m"]
                                                     + rows[1]["settlement_m"], abs=1e-12)
    assert not (out / "procedure" / "before_jump.npz").exists()


@pytest.mark.parametrize("h, error, order, expected", [
    (40, 0.0025, 2, 51),         # kept: 40 x 0.9 sqrt(2) = 50.9
    (40, 0.0001, 2, 80),         # kept far below: at most extrapolated_growth = 2 times
    (40, 0.0, 1, 80),            # no error at all: the same cap
    (100, 0.015, 2, 52),         # undone: 100 x 0.9 sqrt(0.005 / 0.015) = 52.0
    (100, 0.015, 1, 30),         # undone, the error taken linear in h: 100 x 0.9 / 3
    (50, 0.5, 1, 10),            # cut by at most five
    (3, 0.5, 2, 1),              # and to no less than one cycle
])
def test_the_next_jump_is_chosen_as_an_adaptive_solver_chooses_its_step(h, error, order,
                                                                        expected):
    """next_jump with tolerance 0.005 and growth 2: the step-size rule of an adaptive
    ODE solver, the error of an undone jump taken to grow as h^order."""
    from graindyn.protocols.cyclic import next_jump

    assert next_jump(h, error, 0.005, 2.0, order) == expected


def test_an_error_that_does_not_shrink_with_h_is_cut_in_one_retry():
    """Jumps whose error is proportional to h (a rate difference the window measures
    whatever the jump's length) and twice the tolerance at h = 100: the linear rule
    finds a kept h in one retry, the quadratic rule needs more."""
    from graindyn.protocols.cyclic import next_jump

    def retries(order):
        h, n = 100, 0
        while 0.01 * h / 100 > 0.005:
            h, n = next_jump(h, 0.01 * h / 100, 0.005, 2.0, order), n + 1
        return n

    assert retries(1) == 1 and retries(2) == 3


@pytest.mark.parametrize("change, message", [
    (dict(jump_correction="trapezoidal"), "needs an extrapolation and"),
    (dict(jump_tolerance=-0.1), "jump_tolerance"),
    (dict(jump_tolerance=0.01, cycles=20, final_cycles=2), "final_cycles = 2 must be at "
                                                            "least"),
    (dict(undone_error_order=3), "undone_error_order"),
])
def test_bad_jump_tolerances_are_refused(change, message):
    data = copy.deepcopy(SMALL)
    data["protocol"].update({"extrapolation": "linear", "initial_cycles": 2,
                             "computed_cycles": 3, "extrapolated_cycles": 3, **change})
    with pytest.raises(ConfigError, match=message):
        validate(data)


@pytest.mark.parametrize("correction", [{}, {"extrapolation": "linear",
                                              "jump_correction": "trapezoidal"}])
def test_a_run_stopped_before_its_jump_is_checked_resumes_to_the_same_numbers(
        procedure, tmp_path, correction):
    """SIGTERM just after the first jump, before the cycles that check it are done, then
    --resume: the bed kept before the jump (or, for a jump to be corrected, the rates
    it extrapolated) comes back from the run folder, and the run ends with the same
    cycles, kept and rejected jumps and residuals as the one not stopped."""
    finished, results = procedure(cycles=12, jump_tolerance=1e-12, final_cycles=3,
                                  **correction)
    data = copy.deepcopy(SMALL)
    data["protocol"].update({"cycles": 12, "extrapolation": "shenton", "initial_cycles": 2,
                             "computed_cycles": 3, "extrapolated_cycles": 3,
                             "jump_tolerance": 1e-12, "final_cycles": 3, **correction})
    data["output"]["figures"] = False
    (tmp_path / "run.toml").write_text(tomli_w.dumps(data))
    run = tmp_path / "run"
    stop_when_logged(cli("run", tmp_path / "run.toml", "--out", run), run / "run.log",
                     "extrapolated")
    _, meta, _, _ = checkpoint.read(run / "checkpoints" / "checkpoint.h5")
    assert "unchecked" in meta["protocol"]["states"]["cycles"]
    assert (run / "procedure" / "before_jump.npz").exists() != bool(correction)
    proc = cli("run", "--resume", run)
    out, _ = proc.communicate(timeout=900)
    assert proc.returncode == 0, out
    resumed = json.loads((run / "results.json").read_text())
    expected = json.loads((finished / "results.json").read_text())
    for key in ("cycles", "extrapolations", "rejected_extrapolations"):
        assert resumed[key] == expected[key], key
    np.testing.assert_array_equal(load_residuals(run), load_residuals(finished))
