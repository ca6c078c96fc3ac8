"""The integrator study: Oquendo Fig. 2, Perez Fig. 3, an order-of-accuracy
table and the symmetric top of VALIDATION G2, written as figures (PNG), tables (CSV, units in the column names) and
a JSON summary into a run directory.

>>> run_integrator_study(pathlib.Path("runs/integrators"), quick=True)   # doctest: +SKIP
"""
import csv
import json
import math
import pathlib

import numpy as np

from ..analysis.energy import energy_budget
from ..core.species import ContactModel, Material
from ..core.state import State
from ..core.triggers import Periodic
from ..core.walls import Plane, box
from ..engines.soft.integrators import NAMES, STAGES, integrator_id
from ..engines.soft.simulation import Simulation
from ..figures import subplots
from ..physics import reference as ref
from .problems import resting_grain_error, symmetric_top_errors

OQUENDO_SCHEMES = ("verlet", "leap_frog", "optimized_velocity_verlet", "gear5")
PEREZ_SCHEMES = ("velocity_verlet", "beeman", "gear6")


def _write_csv(path, header, rows):
    with open(path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(header)
        writer.writerows(rows)


# ------------------------------------------------------------------ Oquendo Fig. 2
def _hertz_gas(integrator, dt, seed=1, n=50):
    """50 elastic, frictionless Hertz spheres (1 mm diameter) in a closed 8 mm box,
    g = 0, random velocities (0.5 m/s rms per component)."""
    rng = np.random.default_rng(seed)
    radius, side = 0.5e-3, 8e-3
    cells = np.stack(np.meshgrid(*[np.arange(5)] * 3), -1).reshape(-1, 3)
    chosen = cells[rng.choice(len(cells), n, replace=False)]
    positions = (chosen + 0.5) * side / 5 + rng.uniform(-2e-4, 2e-4, chosen.shape)
    state = State.create(positions, np.full(n, radius), 2650.0,
                         velocities=rng.normal(0.0, 0.5, (n, 3)))
    return Simulation(state, [Material(youngs_modulus=1e8)], ContactModel("hertz"),
                      walls=box((0, 0, 0), (side,) * 3, open_top=False),
                      gravity=(0.0, 0.0, 0.0), dt=dt, integrator=integrator,
                      allow_large_dt=True, check_interval=1000)


def _hertz_gas_collision_time():
    """Hertz collision time [s] of two of the gas's spheres at 1 m/s relative speed."""
    m = Material(youngs_modulus=1e8)
    mass = 4.0 / 3.0 * math.pi * 2650.0 * 0.5e-3**3
    e_eff = ref.effective_modulus(m.youngs_modulus, m.poisson_ratio, m.youngs_modulus,
                                  m.poisson_ratio)
    return ref.hertz_collision_time(0.5 * mass, 0.25e-3, e_eff, 1.0)


def oquendo_energy_spread(outdir, quick):
    """<dE^2>^(1/2) of the total mechanical energy over the run versus dt (Oquendo
    Fig. 2): one CSV row per (scheme, dt), and a log-log figure."""
    t_c = _hertz_gas_collision_time()
    ratios = (8, 16, 32) if quick else (5, 8, 12, 16, 24, 32, 48, 64)
    duration = (3e-3 if quick else 2e-2)
    rows = []
    for name in OQUENDO_SCHEMES:
        for ratio in ratios:
            dt = t_c / ratio
            sim = _hertz_gas(name, dt)
            every = max(1, ratio // 8)
            energies = []
            sim.run(steps=int(duration / dt), every=[(Periodic(steps=every), lambda s:
                                                      energies.append(energy_budget(s)["total"]))])
            e = np.array(energies)
            rows.append((name, dt, ratio, float(e.std()), float(e.std() / e.mean())))
    _write_csv(outdir / "oquendo_energy_spread.csv",
               ("scheme", "dt_s", "collision_time_over_dt", "energy_spread_J",
                "relative_energy_spread"), rows)
    fig, ax = subplots(figsize=(5, 4))
    for name in OQUENDO_SCHEMES:
        mine = [r for r in rows if r[0] == name]
        ax.loglog([r[1] for r in mine], [r[3] for r in mine], "o-", label=name)
    ax.set_xlabel("time step dt [s]")
    ax.set_ylabel(r"$\langle \delta E^2 \rangle^{1/2}$ [J]")
    ax.set_title(f"50 Hertz spheres in a box (t_c = {t_c:.3g} s)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(outdir / "oquendo_fig2_energy_spread.png", dpi=120)
    slopes = {}
    for name in OQUENDO_SCHEMES:
        mine = [r for r in rows if r[0] == name]
        slopes[name] = float(np.polyfit(np.log([r[1] for r in mine]),
                                        np.log([r[3] for r in mine]), 1)[0])
    return {"collision_time_s": t_c, "duration_s": duration, "loglog_slope": slopes}


# ------------------------------------------------------------------ Perez Fig. 3
PEREZ_RADIUS, PEREZ_DENSITY, PEREZ_KN, PEREZ_SPEED, PEREZ_DAMPING_RATIO = \
    0.01, 1000.0, 1e4, 0.1, 0.05
PEREZ_ONSET = 20.5   # steps of free flight before the first touch (mid-step)


def _perez_collision(integrator, steps_per_half_period=200):
    """A sphere hits the plane z = 0 at PEREZ_SPEED with the linear spring-dashpot
    (gamma/omega0 = 0.05), no gravity, attraction allowed so the exact solution holds
    (Perez: "ignoring ... the restriction to repulsive forces").  Returns (t [s] from
    the first touch, v_z - v_exact [m/s]) at every step."""
    mass = 4.0 / 3.0 * math.pi * PEREZ_DENSITY * PEREZ_RADIUS**3
    omega0 = math.sqrt(PEREZ_KN / mass)
    gamma = PEREZ_DAMPING_RATIO * omega0
    omega = math.sqrt(omega0**2 - gamma**2)
    half = math.pi / omega
    dt = half / steps_per_half_period
    material = Material(kn=PEREZ_KN, damping_constant=2.0 * gamma * mass)
    state = State.create(np.array([[0.0, 0.0, PEREZ_RADIUS + PEREZ_ONSET * PEREZ_SPEED * dt]]),
                         np.array([PEREZ_RADIUS]), PEREZ_DENSITY,
                         velocities=np.array([[0.0, 0.0, -PEREZ_SPEED]]))
    sim = Simulation(state, [material], ContactModel("hooke", "linear", limit_damping=False),
                     walls=[Plane((0, 0, 0), (0, 0, 1))], gravity=(0.0, 0.0, 0.0), dt=dt,
                     integrator=integrator, allow_large_dt=True)
    times, errors = [], []

    def exact(t):
        if t <= 0.0:
            return -PEREZ_SPEED
        if t >= half:
            return PEREZ_SPEED * math.exp(-gamma * half)
        return -PEREZ_SPEED * math.exp(-gamma * t) * (math.cos(omega * t)
                                                      - gamma / omega * math.sin(omega * t))

    def grab(s):
        t = s.time - PEREZ_ONSET * dt
        times.append(t)
        errors.append(s.state.velocities[0, 2] - exact(t))

    sim.run(steps=int(PEREZ_ONSET + 1.5 * steps_per_half_period),
            every=[(Periodic(steps=1), grab)])
    return np.array(times) / half, np.array(errors)


def perez_collision_error(outdir):
    """Velocity error against the exact linear spring-dashpot collision for modified
    velocity Verlet, Beeman and Gear sixth order, dt = 1/200 of the half period
    (Perez Fig. 3)."""
    curves = {name: _perez_collision(name) for name in PEREZ_SCHEMES}
    t = curves[PEREZ_SCHEMES[0]][0]
    _write_csv(outdir / "perez_collision_velocity_error.csv",
               ("time_over_half_period",) + tuple(f"{n}_velocity_error_m_per_s"
                                                  for n in PEREZ_SCHEMES),
               zip(t, *(curves[n][1] for n in PEREZ_SCHEMES)))
    fig, ax = subplots(figsize=(5, 4))
    for name in PEREZ_SCHEMES:
        ax.plot(*curves[name], label=name)
    ax.set_xlabel("t / (pi/omega)   (t = 0 at first touch)")
    ax.set_ylabel("v - v_exact [m/s]")
    ax.set_title(f"grain on a wall, linear spring-dashpot, v0 = {PEREZ_SPEED} m/s")
    ax.legend()
    fig.tight_layout()
    fig.savefig(outdir / "perez_fig3_collision_velocity_error.png", dpi=120)
    return {name: {"max_abs_velocity_error_m_per_s": float(np.max(np.abs(curves[name][1])))}
            for name in PEREZ_SCHEMES}


# ------------------------------------------------------------------ order table
def order_of_accuracy(outdir, quick):
    """Error against the exact (damped) oscillator for every scheme over a ladder of
    steps per period; the log-log slope (order) and the error at equal cost (force
    evaluations per period, interpolated log-log)."""
    ladder = (50, 100, 200) if quick else (25, 50, 100, 200, 400)
    cost = 200.0
    rows, summary = [], {}
    for damping in (0.0, 2.0):
        for name in NAMES:
            errors = [resting_grain_error(name, n, damping_constant=damping) for n in ladder]
            stages = int(STAGES[integrator_id(name)])
            for n, e in zip(ladder, errors):
                rows.append((name, damping, n, stages * n, e))
            x, y = np.log(ladder), np.log(errors)
            order = float(-np.polyfit(x, y, 1)[0])
            at_cost = float(np.exp(np.interp(np.log(cost / stages), x, y)))
            summary.setdefault(name, {})["damped" if damping else "undamped"] = {
                "order": order, "error_at_200_force_evaluations_per_period": at_cost}
    _write_csv(outdir / "order_of_accuracy.csv",
               ("scheme", "damping_constant_kg_per_s", "steps_per_period",
                "force_evaluations_per_period", "relative_error"), rows)
    _write_csv(outdir / "order_of_accuracy_summary.csv",
               ("scheme", "force_evaluations_per_step", "order_undamped", "order_damped",
                "relative_error_undamped_at_200_evaluations_per_period",
                "relative_error_damped_at_200_evaluations_per_period"),
               [(n, int(STAGES[integrator_id(n)]), s["undamped"]["order"], s["damped"]["order"],
                 s["undamped"]["error_at_200_force_evaluations_per_period"],
                 s["damped"]["error_at_200_force_evaluations_per_period"])
                for n, s in summary.items()])
    fig, axes = subplots(1, 2, figsize=(9, 4), sharey=True)
    for ax, damping in zip(axes, (0.0, 2.0)):
        for name in NAMES:
            mine = [r for r in rows if r[0] == name and r[1] == damping]
            ax.loglog([r[3] for r in mine], [r[4] for r in mine], "o-", label=name)
        ax.set_xlabel("force evaluations per period")
        ax.set_title("undamped" if damping == 0 else "with dashpot (velocity-dependent)")
    axes[0].set_ylabel("relative error after 2 periods")
    axes[1].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(outdir / "order_of_accuracy.png", dpi=120)
    return summary


# ------------------------------------------------------------------ symmetric top
def symmetric_top_table(outdir):
    """VALIDATION G2 for an anisotropic body: the symmetric top of
    problems.symmetric_top at dt |w| = 0.04 ... 0.005, its precession-rate error and
    the conservation of energy, |L| and the world-frame L."""
    rows, summary = [], {}
    for dt_omega in (0.04, 0.02, 0.01, 0.005):
        e = symmetric_top_errors(dt_omega)
        rows.append((dt_omega, e["precession_rate_error"], e["energy_spread"],
                     e["angular_momentum_norm_spread"], *e["world_angular_momentum_error"]))
        summary[str(dt_omega)] = e
    _write_csv(outdir / "symmetric_top.csv",
               ("dt_times_omega", "precession_rate_relative_error", "energy_spread_relative",
                "angular_momentum_norm_spread_relative",
                "world_angular_momentum_error_first_half", "world_angular_momentum_error_second_half"),
               rows)
    return summary


def run_integrator_study(outdir: pathlib.Path, quick: bool = False) -> dict:
    """Run the four parts of the study, write figures, tables and ``summary.json`` into
    ``outdir`` (created) and return the summary.  quick=True: fewer and shorter runs,
    for the test suite (under a minute on 2 cores once compiled)."""
    outdir = pathlib.Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    summary = {"quick": quick,
               "oquendo_fig2": oquendo_energy_spread(outdir, quick),
               "perez_fig3": perez_collision_error(outdir),
               "order_of_accuracy": order_of_accuracy(outdir, quick),
               "symmetric_top": symmetric_top_table(outdir)}
    (outdir / "summary.json").write_text(json.dumps(summary, indent=2))
    return summary
