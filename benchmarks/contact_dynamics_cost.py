"""The contact dynamics engine's cost against the number of grains, and the same gravity
deposition with the soft engine (time to settle, packing fraction).

    NUMBA_NUM_THREADS=1 nice -n 19 python benchmarks/contact_dynamics_cost.py \
        [--n2 50 100 200 400 800] [--n3 27 64 125 216 512] [--seeds 3] \
        [--packing-n2 400] [--packing-n3 512] [--youngs 1e9] [--stiff-youngs 6.3e10] \
        [--table /tmp/cd_cost_table.md]

Prints a line per run, then markdown tables (also written to --table) and the peak
memory of the process.  The defaults take about 10 minutes of CPU on one thread.

Why: Perez's review of contact dynamics states that its cost grows as N^2 in 2D and
N^2.5 in 3D, and rigid grains must deposit to the packing fraction soft grains reach.

The pile (both tasks, both engines): disks (2D) or spheres (3D) of diameters uniform in
[1.6, 2.4] mm (mean d = 2 mm; polydisperse so that the disks do not crystallise),
density 2650 kg/m^3 (2D: areal 2650 * d = 5.3 kg/m^2, a slice one diameter thick),
mu = 0.4 (grains and walls, static = sliding), restitution e = 0.3, gravity 9.81 m/s^2,
in a box open at the top whose width is chosen so that the settled pile is about as
tall as it is wide (nx = round(0.74 sqrt N) lattice sites across in 2D,
round(0.72 N^(1/3)) in 3D, at least 2): N grows in every direction.  The grains start
on the loose lattice of protocols.prepare.lattice_insertion (spacing 1.1 d_max) with
random velocities of 0.05 m/s, as the deposition protocol starts them.

Settled (both engines): the kinetic energy, rotation included, at most 1e-6 of the
gravitational energy above the lowest grain (EnergyRatioBelow(1e-6), prepare.settle's
default) at a step and again 0.02 s later (without the second look, a pile in which a
surface grain rolls passes through a low energy and is taken for settled); at most
--max-time simulated seconds.  The 0.02 s window counts in the settling cost.

Task A (contact dynamics only; dt = 1e-4 s, theta = 0.5, tolerance 1e-4, at most 1000
sweeps a step, detection gap 0.25 R_min: the default 0.1 R_min is less than the fall of
the top grains in one step, up to 1.4 m/s * 1e-4 s = 0.14 mm), for each N, seed 0:
  * settling from the lattice: steps, NLGS sweeps per step (engine.mean_iterations),
    wall and CPU ms per step, steps that ended above the tolerance and the worst
    residual, the largest speed and overlap once settled;
  * settled: --settled-steps more steps of the resting pile (warm start);
  * cold start: the settled pile, every impulse set to zero (no warm start), one step
    with a cap of --cold-cap sweeps, to the run's tolerance 1e-4 and to --tight
    (default 1e-5; the pile restored between the two): sweeps, contacts carrying a
    force, CPU time, sweeps x contacts (the solve's work in contact updates).  Tighter
    than about 1e-6 the NLGS stalls on these piles (1e5 sweeps leave 1e-6 to 3e-6).
  then least-squares exponents b of y ~ N^b (log-log, with the standard error of the
  slope) for the per-step, per-settle and cold-start costs, to set beside Perez's.

Task B: --seeds piles of --packing-n2 disks and --packing-n3 spheres settled by both
engines to the same criterion: contact dynamics as above (seed 0 is task A's run when
the size is in its list), and the soft engine (Hertz normal force, Tsuji damping for
e = 0.3, Mindlin tangential spring with the Coulomb cap mu = 0.4, no tangential
damping; Young's modulus --youngs, Poisson 0.3; the suggested step, 0.2 of the Rayleigh
time; velocity Verlet).  Reported: wall and CPU time to settle, the simulated settling
time, the packing fraction of (1) the helper's core slab (analysis.packing through
prepare.settle_report: the full width, two mean diameters off the floor and off the
top of the highest grain) and (2) a core box that also keeps one mean diameter off
each side wall, measured on a regular grid of points (spacing d/20) as the fraction of
points inside a grain; the mean over seeds with the standard error.  The glass
modulus --stiff-youngs is timed on seed 0 over --stiff-time simulated seconds only
and its settling cost ESTIMATED: (a) from that (CPU per step x settling time / dt; a
lower bound, the stretch being mostly free fall), (b) the softer runs' CPU time
scaled by the ratio of the time steps.

One thread on a machine shared with other work: CPU time (process_time) is reported
beside wall time because it is less disturbed by the other work.
"""
import argparse
import math
import os
import resource
import sys
import time
import warnings

import numpy as np

D_MEAN = 2e-3                  # mean diameter [m]
D_MIN, D_MAX = 1.6e-3, 2.4e-3  # [m]
RHO = 2650.0                   # [kg/m^3]
MU = 0.4
E_N = 0.3
G = 9.81
DT = 1e-4
THETA = 0.5
TOLERANCE = 1e-4
LATTICE_GAP = 0.1
LATTICE_SPEED = 0.05           # [m/s]
RATIO = 1e-6                   # settled: kinetic <= RATIO x gravitational energy ...
WINDOW = 0.02                  # ... at a step and again this long after [s]


def peak_memory():
    """Peak resident memory of the process [bytes]."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def pile(dim, n, seed):
    """A loose lattice of n polydisperse grains with random velocities in an open box:
    (state, walls, width [m], gravity)."""
    import graindyn as gd
    from graindyn.protocols.prepare import BoxRegion, lattice_insertion

    rng = np.random.default_rng(seed)
    radii = gd.sample_radii(n, "uniform", rng, d_min=D_MIN, d_max=D_MAX)
    a = D_MAX * (1 + LATTICE_GAP)
    nx = max(2, round((0.74 * math.sqrt(n)) if dim == 2 else 0.72 * n ** (1 / 3)))
    width = nx * a
    layers = math.ceil(n / nx ** (dim - 1))
    height = (layers + 0.5) * a
    region = BoxRegion((0.0,) * dim, (width,) * (dim - 1) + (height,))
    positions, velocities = lattice_insertion(radii, region, rng, dim=dim,
                                              gap=LATTICE_GAP, speed=LATTICE_SPEED)
    density = RHO if dim == 3 else RHO * D_MEAN
    state = gd.State.create(positions[:, :dim], radii, density, dim=dim,
                            velocities=velocities)
    walls = gd.box((0.0,) * dim, (width,) * (dim - 1) + (2 * height,), open_top=True,
                   dim=dim)
    gravity = (0.0, 0.0, -G) if dim == 3 else (0.0, -G, 0.0)
    return state, walls, width, gravity


def contact_dynamics(dim, n, seed, max_iterations=1000):
    import graindyn as gd
    from graindyn.engines.contact_dynamics.engine import ContactDynamics

    state, walls, width, gravity = pile(dim, n, seed)
    material = gd.Material(density=RHO if dim == 3 else RHO * D_MEAN, restitution=E_N,
                           friction_static=MU, friction_sliding=MU)
    engine = ContactDynamics(state, [material], walls=walls, gravity=gravity, dt=DT,
                             theta=THETA, gap=0.25 * float(state.radii.min()),
                             tolerance=TOLERANCE, max_iterations=max_iterations)
    return engine, width


def soft(dim, n, seed, youngs):
    import graindyn as gd

    state, walls, width, gravity = pile(dim, n, seed)
    density = RHO if dim == 3 else RHO * D_MEAN
    material = gd.Material(density=density, youngs_modulus=youngs, poisson_ratio=0.3,
                           restitution=E_N, friction_static=MU, friction_sliding=MU)
    sim = gd.Simulation(state, [material], gd.ContactModel("hertz", "tsuji", "mindlin"),
                        walls=walls, gravity=gravity)
    return sim, width


def total_sweeps(engine):
    from graindyn.engines.contact_dynamics import stepping as st
    return int(engine.counters[st.TOTAL_ITERATIONS])


class Timed:
    """Wall and CPU seconds of a block."""

    def __enter__(self):
        self.w0, self.c0 = time.perf_counter(), time.process_time()
        return self

    def __exit__(self, *exc):
        self.wall = time.perf_counter() - self.w0
        self.cpu = time.process_time() - self.c0


def cd_run(engine, **kw):
    """engine.run(**kw) with the not-converged warning caught: (status, Timed, sweeps,
    steps, not converged)."""
    s0, it0, nc0 = engine.step, total_sweeps(engine), engine.not_converged
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        with Timed() as t:
            status = engine.run(**kw)
    steps = engine.step - s0
    return status, t, total_sweeps(engine) - it0, steps, engine.not_converged - nc0


def max_speed(engine):
    return float(np.linalg.norm(engine.state.velocities, axis=1).max())


def energy_ratio(engine):
    """Kinetic (with rotation) over gravitational energy above the lowest grain, as
    core.triggers.EnergyRatioBelow reads it."""
    st = engine.state
    free = st.fixed == 0
    g = np.asarray(engine.gravity)
    up = -g / np.linalg.norm(g)
    h = st.positions @ up
    potential = float(np.sum(st.masses[free] * np.linalg.norm(g) * (h[free] - h[free].min())))
    w = st.angular_velocities if st.dim == 3 else st.angular_velocities[:, 2:]
    kinetic = 0.5 * float(np.sum(st.masses[free] * np.sum(st.velocities[free] ** 2, 1))
                          + np.sum(st.inertias[free] * np.sum(w[free] ** 2, 1)))
    return kinetic / potential


def settle(engine, max_time, ratio=RATIO, window=WINDOW):
    """Run either engine until the kinetic energy is at most ``ratio`` of the
    gravitational energy (EnergyRatioBelow) at a step and still is ``window`` [s] later
    (a pile can pass through a low energy without having stopped: a grain rolling on
    the surface), or ``max_time`` [s] of simulated time has passed: (reached, Timed).
    The window counts in the settling cost."""
    from graindyn.core.triggers import EnergyRatioBelow

    reached = False
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        with Timed() as t:
            while engine.time < max_time:
                if engine.run(time=max_time - engine.time,
                              until=EnergyRatioBelow(ratio)) != "condition":
                    break
                engine.run(time=window)
                if energy_ratio(engine) <= ratio:
                    reached = True
                    break
    return reached, t


def penetration(state):
    """The largest overlap of two grains over the mean radius (0 when none)."""
    from scipy.spatial import cKDTree

    dim = state.dim
    p = state.positions[:, :dim]
    pairs = cKDTree(p).query_pairs(2 * state.radii.max(), output_type="ndarray")
    if pairs.size == 0:
        return 0.0
    dist = np.linalg.norm(p[pairs[:, 0]] - p[pairs[:, 1]], axis=1)
    over = state.radii[pairs[:, 0]] + state.radii[pairs[:, 1]] - dist
    return float(max(over.max(), 0.0) / state.radii.mean())


def core_box_fraction(state, width, spacing=D_MEAN / 20):
    """Solid fraction of the box one mean diameter off each side wall, two off the
    floor and two below the top of the highest grain, on a regular grid of points;
    None when the pile is too small for such a box."""
    from scipy.spatial import cKDTree

    dim = state.dim
    p = state.positions[:, :dim]
    top = float(np.max(p[:, -1] + state.radii))
    lo = np.array([D_MEAN] * (dim - 1) + [2 * D_MEAN])
    hi = np.array([width - D_MEAN] * (dim - 1) + [top - 2 * D_MEAN])
    if np.any(hi - lo < 2 * D_MEAN):
        return None
    axes = [np.arange(lo[k] + 0.5 * spacing, hi[k], spacing) for k in range(dim)]
    points = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, dim)
    tree = cKDTree(p)
    k = 4 if dim == 2 else 6
    dist, idx = tree.query(points, k=k, distance_upper_bound=state.radii.max())
    rad = np.concatenate([state.radii, [0.0]])[np.minimum(idx, state.n)]
    inside = np.any(dist < rad, axis=1)
    return float(inside.mean())


def packing(engine, width, reached):
    """(phi of the helper's core slab, phi of the core box, pile height [m])."""
    from graindyn.core.triggers import EnergyRatioBelow
    from graindyn.protocols.prepare import settle_report

    dim = engine.state.dim
    report = settle_report(engine, reached, EnergyRatioBelow(RATIO),
                           bottom_wall="zlo" if dim == 3 else "ylo",
                           cross_section=width ** (dim - 1))
    return report.get("packing_fraction_core"), core_box_fraction(engine.state, width), \
        report["bed_height_m"]


def warm_up(youngs):
    """Compile both engines' kernels (cached on disk) on small piles, untimed."""
    for dim in (2, 3):
        e, _ = contact_dynamics(dim, 8, 99)
        cd_run(e, steps=50)
        cold_start(e, 1e-4, 10)
        for y in youngs:
            s, _ = soft(dim, 8, 99, y)
            settle(s, 0.002)


def cold_start(engine, tolerance, cap):
    """One step of the settled pile from zero impulses (no warm start) with at most
    ``cap`` sweeps to ``tolerance``: dict of sweeps, residual, contacts carrying a
    force, wall and CPU s, capped; the engine is put back as it was."""
    from graindyn.engines.contact_dynamics import stepping as st

    saved = engine.snapshot()
    engine.lists.impulses[:] = 0.0
    engine.lists.wall_impulses[:] = 0.0
    engine.counters[st.MAX_ITERATIONS] = cap
    engine.clock[st.TOLERANCE] = tolerance
    _, t, sweeps, _, nc = cd_run(engine, steps=1)
    contacts = engine.contacts().i.size + engine.wall_contacts().grain.size
    residual = engine.last_residual
    engine.restore(saved)
    return {"sweeps": sweeps, "residual": residual, "contacts": contacts,
            "wall_s": t.wall, "cpu_s": t.cpu, "capped": nc > 0}


def cd_settle(dim, n, seed, max_time):
    """Contact dynamics from the lattice to settled: (row, engine, width)."""
    engine, width = contact_dynamics(dim, n, seed)
    it0, nc0 = total_sweeps(engine), engine.not_converged
    reached, t = settle(engine, max_time)
    steps = engine.step
    phi_slab, phi_box, height = packing(engine, width, reached)
    row = {"dim": dim, "n": n, "seed": seed, "width_d": width / D_MEAN,
           "height_d": height / D_MEAN, "reached": reached, "steps": steps, "dt": DT,
           "time_s": engine.time, "sweeps": (total_sweeps(engine) - it0) / max(steps, 1),
           "mean_iterations": engine.mean_iterations,
           "ms": 1e3 * t.wall / max(steps, 1), "cpu_ms": 1e3 * t.cpu / max(steps, 1),
           "wall_s": t.wall, "cpu_s": t.cpu, "nc": engine.not_converged - nc0,
           "worst": engine.worst_residual, "phi_slab": phi_slab, "phi_box": phi_box,
           "penetration": penetration(engine.state), "vmax": max_speed(engine)}
    print(f"cd dim {dim} N {n} seed {seed}: box {row['width_d']:.1f} d, pile "
          f"{row['height_d']:.1f} d; {'settled' if reached else 'NOT settled'} at "
          f"{engine.time:.3f} s, {steps} steps, {t.wall:.2f} s wall ({t.cpu:.2f} CPU), "
          f"{row['sweeps']:.1f} sweeps/step, {row['nc']} steps not converged (worst "
          f"{row['worst']:.2g}); phi slab {phi_slab} box {phi_box}; max overlap "
          f"{row['penetration']:.2g} R", flush=True)
    return row, engine, width


def cost_one(dim, n, max_time, settled_steps, cold_cap, tight):
    row, engine, width = cd_settle(dim, n, 0, max_time)
    _, t, sweeps, steps, nc = cd_run(engine, steps=settled_steps)
    row.update(rest_sweeps=sweeps / max(steps, 1), rest_ms=1e3 * t.wall / max(steps, 1),
               rest_cpu_ms=1e3 * t.cpu / max(steps, 1), rest_nc=nc,
               rest_vmax=max_speed(engine),
               contacts=engine.contacts().i.size + engine.wall_contacts().grain.size)
    row["cold"] = {tol: cold_start(engine, tol, cold_cap) for tol in (TOLERANCE, tight)}
    c4, c5 = row["cold"][TOLERANCE], row["cold"][tight]
    print(f"    settled: {row['rest_sweeps']:.2f} sweeps/step, {row['rest_ms']:.3f} ms/step "
          f"({row['rest_cpu_ms']:.3f} CPU), {nc} not converged, {row['contacts']} "
          f"contacts, max speed {row['rest_vmax']:.2g} m/s; cold start {c4['sweeps']} "
          f"sweeps to {TOLERANCE:g} ({c4['cpu_s']:.3f} s CPU), {c5['sweeps']} to {tight:g}"
          f" ({c5['cpu_s']:.3f} s CPU, residual {c5['residual']:.2g}"
          f"{', CAPPED' if c5['capped'] else ''})", flush=True)
    return row


def soft_settle(dim, n, seed, youngs, max_time):
    sim, width = soft(dim, n, seed, youngs)
    reached, t = settle(sim, max_time)
    phi_slab, phi_box, height = packing(sim, width, reached)
    row = {"dim": dim, "n": n, "seed": seed, "reached": reached, "steps": sim.step,
           "dt": sim.dt, "time_s": sim.time, "wall_s": t.wall, "cpu_s": t.cpu,
           "phi_slab": phi_slab, "phi_box": phi_box, "height_d": height / D_MEAN,
           "penetration": penetration(sim.state), "vmax": max_speed(sim)}
    print(f"soft dim {dim} N {n} seed {seed} E {youngs:.3g} Pa: dt {sim.dt:.3g} s; "
          f"{'settled' if reached else 'NOT settled'} at {sim.time:.3f} s, {sim.step} "
          f"steps, {t.wall:.2f} s wall ({t.cpu:.2f} CPU); phi slab {phi_slab} box "
          f"{phi_box}; max overlap {row['penetration']:.2g} R", flush=True)
    return row


def soft_segment(dim, n, youngs, duration):
    """The soft engine at ``youngs`` on seed 0's pile for ``duration`` simulated
    seconds from the lattice (the impacts of the deposition included): dt and the wall
    and CPU seconds per step."""
    sim, _ = soft(dim, n, 0, youngs)
    with Timed() as t:
        sim.run(time=duration)
    row = {"dt": sim.dt, "steps": sim.step, "wall_per_step": t.wall / sim.step,
           "cpu_per_step": t.cpu / sim.step}
    print(f"soft dim {dim} N {n} E {youngs:.3g} Pa: dt {sim.dt:.3g} s, {sim.step} steps "
          f"in {t.wall:.2f} s wall ({t.cpu:.2f} CPU)", flush=True)
    return row


def fit(n, y):
    """Slope b of log y = b log n + c and the standard error of b (None with < 3
    points)."""
    n, y = np.asarray(n, float), np.asarray(y, float)
    ok = y > 0
    if ok.sum() < 3:
        return None, None
    x, z = np.log(n[ok]), np.log(y[ok])
    b, c = np.polyfit(x, z, 1)
    resid = z - (b * x + c)
    err = math.sqrt(resid @ resid / (ok.sum() - 2) / np.sum((x - x.mean()) ** 2))
    return float(b), err


def mean_se(values):
    """(mean, standard error, count) of the values that are not None."""
    v = np.array([x for x in values if x is not None], float)
    if v.size == 0:
        return float("nan"), float("nan"), 0
    se = float(v.std(ddof=1) / math.sqrt(v.size)) if v.size > 1 else float("nan")
    return float(v.mean()), se, v.size


def fmt_fit(f):
    b, e = f
    return "n/a" if b is None else f"{b:.2f} ± {e:.2f}"


def cost_tables(cost, tight):
    out = []
    for dim in (2, 3):
        rows = [r for r in cost if r["dim"] == dim]
        if not rows:
            continue
        grains = "disks" if dim == 2 else "spheres"
        out += [f"### {dim}D ({grains}): settling from the lattice", "",
                "| N | box width / pile height [d] | steps to settle (sim. s) | sweeps "
                "per step | ms/step wall | ms/step CPU | CPU s to settle | steps not "
                "converged (worst residual) | max speed settled [m/s] | max overlap / R |",
                "|" + "---|" * 10]
        for r in rows:
            out.append(
                f"| {r['n']} | {r['width_d']:.1f} / {r['height_d']:.1f} | {r['steps']}"
                f"{'' if r['reached'] else ' (cap, not settled)'} ({r['time_s']:.3f}) | "
                f"{r['sweeps']:.1f} | {r['ms']:.2f} | {r['cpu_ms']:.2f} | "
                f"{r['cpu_s']:.1f} | {r['nc']} ({r['worst']:.2g}) | {r['vmax']:.2g} | "
                f"{r['penetration']:.2g} |")
        out += ["", f"### {dim}D ({grains}): settled (warm start) and cold start (one step"
                " of the settled pile from zero impulses)", "",
                "| N | contacts | sweeps/step settled | ms/step settled wall (CPU) | "
                "not converged settled | cold sweeps to 1e-4 | cold CPU s to 1e-4 | "
                f"cold sweeps to {tight:g} (residual) | cold CPU s to {tight:g} | "
                f"cold work to {tight:g}: sweeps x contacts |", "|" + "---|" * 10]
        for r in rows:
            c4, c5 = r["cold"][TOLERANCE], r["cold"][tight]
            cap = lambda c: " (cap)" if c["capped"] else ""
            out.append(
                f"| {r['n']} | {r['contacts']} | {r['rest_sweeps']:.2f} | "
                f"{r['rest_ms']:.3f} ({r['rest_cpu_ms']:.3f}) | {r['rest_nc']} | "
                f"{c4['sweeps']}{cap(c4)} | {c4['cpu_s']:.3f} | {c5['sweeps']}{cap(c5)} "
                f"({c5['residual']:.2g}) | {c5['cpu_s']:.3f} | "
                f"{c5['sweeps'] * c5['contacts']:.3g} |")
        n = [r["n"] for r in rows]
        quantities = [
            ("wall ms per step, settling", [r["ms"] for r in rows]),
            ("CPU ms per step, settling", [r["cpu_ms"] for r in rows]),
            ("sweeps per step, settling", [r["sweeps"] for r in rows]),
            ("steps to settle", [r["steps"] for r in rows]),
            ("CPU s to settle (per settle = per step x steps)", [r["cpu_s"] for r in rows]),
            ("CPU ms per step, settled (warm start)", [r["rest_cpu_ms"] for r in rows]),
            ("contacts", [r["contacts"] for r in rows]),
            ("cold-start sweeps to 1e-4", [r["cold"][TOLERANCE]["sweeps"] for r in rows]),
            (f"cold-start sweeps to {tight:g}", [r["cold"][tight]["sweeps"] for r in rows]),
            (f"cold-start work to {tight:g} (sweeps x contacts)",
             [r["cold"][tight]["sweeps"] * r["cold"][tight]["contacts"] for r in rows]),
            (f"cold-start CPU s to {tight:g}", [r["cold"][tight]["cpu_s"] for r in rows]),
        ]
        out += ["", f"### {dim}D exponents b of y ~ N^b (least squares on log y against "
                f"log N over N = {', '.join(map(str, n))}; ± the standard error of the "
                f"slope from the scatter about the line; Pérez: N^{2 if dim == 2 else 2.5})",
                "", "| quantity y | b |", "|---|---|"]
        out += [f"| {name} | {fmt_fit(fit(n, y))} |" for name, y in quantities]
        out.append("")
    return out


def versus_tables(versus, stiff, stiff_youngs, stiff_time):
    out = ["| dim | N | engine | E [Pa] | seeds settled | dt [s] | simulated settle "
           "time [s] | steps | wall s to settle | CPU s to settle | phi core slab "
           "(helper) | phi core box (grid) | largest max speed settled [m/s] | max overlap / "
           "R |", "|" + "---|" * 14]
    for (dim, n), group in sorted(versus.items()):
        cd = group["contact_dynamics"]
        for name, youngs, rs in [("contact dynamics", None, cd)] + \
                [("soft", y, r) for y, r in group["soft"].items()]:
            if not rs:
                continue

            def pm(key, f):
                m, se, k = mean_se([r[key] for r in rs])
                return f.format(m) + ("" if k < 2 else " ± " + f.format(se))
            out.append(f"| {dim} | {n} | {name} | {'rigid' if youngs is None else f'{youngs:.3g}'}"
                       f" | {sum(r['reached'] for r in rs)}/{len(rs)} | {rs[0]['dt']:.3g} | "
                       f"{pm('time_s', '{:.3f}')} | {pm('steps', '{:.0f}')} | "
                       f"{pm('wall_s', '{:.1f}')} | {pm('cpu_s', '{:.1f}')} | "
                       f"{pm('phi_slab', '{:.4f}')} | {pm('phi_box', '{:.4f}')} | "
                       f"{max(r['vmax'] for r in rs):.2g} | "
                       f"{max(r['penetration'] for r in rs):.2g} |")
    out += ["", "Differences soft - contact dynamics over the seeds that both engines "
            "settled (± the standard errors combined), and the ratio of their mean CPU "
            "(wall) times to settle:", "",
            "| dim | N | E [Pa] | seeds (both settled) | soft / CD CPU time | soft / CD wall "
            "time | delta phi core slab | delta phi core box |",
            "|---|---|---|---|---|---|---|---|"]
    for (dim, n), group in sorted(versus.items()):
        cd = group["contact_dynamics"]
        for youngs, sf in group["soft"].items():
            pairs = [(a, b) for a, b in zip(cd, sf) if a["reached"] and b["reached"]]
            k = len(pairs)
            if k == 0:
                continue
            ref, soft_rows = [a for a, _ in pairs], [b for _, b in pairs]

            def ratio(key):
                return mean_se([r[key] for r in soft_rows])[0] / \
                    mean_se([r[key] for r in ref])[0]

            def delta(key):
                a, sa, _ = mean_se([r[key] for r in ref])
                b, sb, _ = mean_se([r[key] for r in soft_rows])
                return f"{b - a:+.4f}" + ("" if k < 2 else f" ± {math.hypot(sa, sb):.4f}")
            seeds = ", ".join(str(a["seed"]) for a in ref)
            out.append(f"| {dim} | {n} | {youngs:.3g} | {k} ({seeds}) | "
                       f"{ratio('cpu_s'):.2f} | {ratio('wall_s'):.2f} | "
                       f"{delta('phi_slab')} | {delta('phi_box')} |")
    if stiff:
        out += ["", f"Soft engine at E = {stiff_youngs:.3g} Pa (glass), ESTIMATED, not a "
                "measured settle.  (a) lower bound: CPU per step measured on seed 0 over "
                f"the first {stiff_time:g} s of the deposition x (mean simulated settling "
                "time of the soft runs above) / dt; that stretch is mostly free fall with "
                "few contacts, so its steps are cheaper than a settling pile's.  (b) the "
                "soft runs above scaled by their dt over this dt (the same steps' cost and "
                "the same settling time assumed; the overlaps are smaller).  Ratios are to "
                "the mean CPU time of the contact dynamics runs that settled:", "",
                "| dim | N | dt [s] | steps measured | CPU ms/step measured | CPU ms/step "
                "of the softer runs | est. steps to settle | (a) est. CPU s | (a) soft / "
                "CD | (b) est. CPU s | (b) soft / CD |", "|" + "---|" * 11]
        for (dim, n), r in sorted(stiff.items()):
            group = versus[(dim, n)]
            soft_rows = [x for x in next(iter(group["soft"].values())) if x["reached"]]
            t_settle = mean_se([x["time_s"] for x in soft_rows])[0]
            steps = t_settle / r["dt"]
            lower = steps * r["cpu_per_step"]
            soft_cpu = mean_se([x["cpu_s"] for x in soft_rows])[0]
            per_step = mean_se([x["cpu_s"] / x["steps"] for x in soft_rows])[0]
            scaled = soft_cpu * soft_rows[0]["dt"] / r["dt"]
            cd_cpu = mean_se([x["cpu_s"] for x in group["contact_dynamics"]
                              if x["reached"]])[0]
            out.append(f"| {dim} | {n} | {r['dt']:.3g} | {r['steps']} | "
                       f"{1e3 * r['cpu_per_step']:.4f} | {1e3 * per_step:.4f} | "
                       f"{steps:.3g} | {lower:.0f} | {lower / cd_cpu:.2f} | {scaled:.0f} | "
                       f"{scaled / cd_cpu:.2f} |")
    out.append("")
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--n2", type=int, nargs="*", default=[50, 100, 200, 400, 800])
    parser.add_argument("--n3", type=int, nargs="*", default=[27, 64, 125, 216, 512])
    parser.add_argument("--packing-n2", type=int, default=400, help="0: none")
    parser.add_argument("--packing-n3", type=int, default=512, help="0: none")
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--youngs", type=float, default=1e9,
                        help="soft engine's Young's modulus for every seed [Pa]")
    parser.add_argument("--stiff-youngs", type=float, default=6.3e10,
                        help="a stiffer modulus timed on seed 0 only [Pa] (0: none)")
    parser.add_argument("--stiff-time", type=float, default=0.02,
                        help="simulated seconds the stiffer modulus is timed over [s]")
    parser.add_argument("--max-time", type=float, default=1.5,
                        help="cap on the simulated settling time [s]")
    parser.add_argument("--settled-steps", type=int, default=200)
    parser.add_argument("--cold-cap", type=int, default=30000)
    parser.add_argument("--tight", type=float, default=1e-5,
                        help="the cold start's tight tolerance")
    parser.add_argument("--table", default="/tmp/cd_cost_table.md")
    parser.add_argument("--json", default=None, help="also write every row here")
    args = parser.parse_args()
    start = time.perf_counter()
    cpu0 = time.process_time()
    youngs = [args.youngs] + ([args.stiff_youngs] if args.stiff_youngs > 0 else [])
    warm_up(youngs)
    stiff = {}
    cost, kept = [], {}
    for dim, sizes in ((2, args.n2), (3, args.n3)):
        for n in sizes:
            kept[(dim, n)] = cost_one(dim, n, args.max_time, args.settled_steps,
                                      args.cold_cap, args.tight)
            cost.append(kept[(dim, n)])
    versus = {}
    for dim, n in ((2, args.packing_n2), (3, args.packing_n3)):
        if n <= 0 or args.seeds < 1:
            continue
        group = versus[(dim, n)] = {"contact_dynamics": [], "soft": {args.youngs: []}}
        for seed in range(args.seeds):
            row = kept[(dim, n)] if seed == 0 and (dim, n) in kept else \
                cd_settle(dim, n, seed, args.max_time)[0]
            group["contact_dynamics"].append(row)
            group["soft"][args.youngs].append(soft_settle(dim, n, seed, args.youngs,
                                                          args.max_time))
        if args.stiff_youngs > 0:
            stiff[(dim, n)] = soft_segment(dim, n, args.stiff_youngs, args.stiff_time)
    elapsed, cpu = time.perf_counter() - start, time.process_time() - cpu0
    command = "NUMBA_NUM_THREADS=1 nice -n 19 python " + " ".join(sys.argv)
    head = ["# Contact dynamics: cost against N, and the soft engine on the same pile", "",
            "Command:", "", "    " + command, "",
            f"Whole run: {elapsed / 60:.1f} min wall, {cpu / 60:.1f} min CPU, one numba "
            "thread at nice 19 on a machine of 2 cores shared with other work (load "
            f"average at the end {os.getloadavg()[0]:.1f}): wall times are noisy and "
            "inflated by the other work; CPU times (process_time) are less so, but "
            "still share caches and memory bandwidth.", "",
            f"Settled: kinetic energy (with rotation) at most {RATIO:g} of the "
            "gravitational energy above the lowest grain at a step (EnergyRatioBelow) and "
            f"again {WINDOW:g} s later (cap {args.max_time:g} s simulated).", ""]
    text = "\n".join(head + ["## Task A: contact dynamics cost against N", ""]
                     + cost_tables(cost, args.tight)
                     + (["## Task B: the same deposition with the soft engine", ""]
                        + versus_tables(versus, stiff, args.stiff_youngs, args.stiff_time)
                        if versus else []))
    if versus:
        text += "\n".join(["", "Per seed (settled, simulated settling time [s], CPU s, phi "
                           "core slab, phi core box):", "",
                           "| dim | N | engine | seed | settled | sim. s | CPU s | phi slab | "
                           "phi box |", "|---|---|---|---|---|---|---|---|---|"]
                          + [f"| {dim} | {n} | {name} | {r['seed']} | {r['reached']} | "
                             f"{r['time_s']:.3f} | {r['cpu_s']:.1f} | {r['phi_slab']:.4f} | "
                             f"{r['phi_box']:.4f} |"
                             for (dim, n), g in sorted(versus.items())
                             for name, rows in [("CD", g["contact_dynamics"])]
                             + [(f"soft {y:.3g}", v) for y, v in g["soft"].items()]
                             for r in rows]) + "\n"
    with open(args.table, "w") as f:
        f.write(text + "\n")
    if args.json:
        import json
        with open(args.json, "w") as f:
            json.dump({"cost": cost, "versus": {f"{d} {n}": g for (d, n), g in
                                                versus.items()},
                       "stiff": {f"{d} {n}": r for (d, n), r in stiff.items()}}, f,
                      indent=1, default=str)
    print(text)
    print(f"peak_rss_bytes {peak_memory()}; table written to {args.table}")


if __name__ == "__main__":
    main()
