"""graindyn's contact dynamics engine against Siconos, on the same rigid-grain problems.

    nice -n 19 python comparisons/siconos_contact_dynamics.py [--markdown FILE]

(prints the markdown tables; --markdown also writes them to FILE; about 3 minutes on
two shared cores, nearly all of it in Siconos' pile).

Siconos is not a dependency of graindyn: this script runs its half in a subprocess of
Debian's /usr/bin/python3 (`apt-get install -y python3-siconos`, Siconos 4.4; another
interpreter with `--siconos-python PATH`) and stops with that advice when it cannot
import it.  The two halves exchange the initial states and the results as .npz files
(the script calls itself with `--siconos-worker DIR`).  Both run on one thread
(NUMBA_NUM_THREADS, OMP_NUM_THREADS and OPENBLAS_NUM_THREADS set to 1 here).

Problems, same initial state and parameters in both codes (SI units, R = 1 mm,
rho = 2650, g = 9.81 m/s^2, dt = 1e-4 s, theta = 0.5, Newton restitution, Coulomb
friction mu_s = mu_d, Gauss-Seidel sweeps with the same tolerance and sweep cap):

1. Column: 10 spheres (3D) touching one above the other on a floor plane, at rest,
   e = 0.5, mu = 0.4, 200 steps, at tolerance 1e-4 and 1e-10.  The force below grain k
   must be the weight of grains k..N-1.  Compared: those forces, the heights after the
   run, the penetration, sweeps per step and time per step.
2. Pile: 200 disks (2D, radii uniform in R (1 +- 0.05)) from a square lattice of pitch
   2.4 R (random offsets of 0.05 R) falling into a box (floor and two side walls of
   width 48 R), e = 0.3, mu = 0.4 on all contacts, tolerance 1e-4, 1000 sweeps at most,
   1500 steps (0.15 s).  A falling and colliding pile is chaotic: grain positions are
   compared one by one only over the early steps (how fast the two runs part), the end
   state by its statistics: packing fraction from the mean height
   (phi = sum pi r^2 / (2 L <y>)), the highest grain, the coordination of the
   force-carrying grain-grain contacts (2 N_c / N), the floor's normal force and the
   vertical force of all walls against the weight, the largest overlap and speed.

The Siconos models: the column is built by hand (LagrangianLinearTIDS of mass
diag(m, m, m, I, I, I) per sphere, LagrangianLinearTIR with the exact normal and
tangential rows, FrictionContact(3) with SICONOS_FRICTION_3D_NSGS); the pile uses the
native 2D bodies (Disk, DiskDiskR, DiskPlanR: FrictionContact(2),
SICONOS_FRICTION_2D_NSGS) with the candidate pairs found here in numpy (pairs and walls
closer than 0.3 R, lists rebuilt when a disk has moved 0.075 R; Siconos' SpaceFilter
needs an integer cell size, useless with millimetre grains).  MoreauJeanOSI(theta=0.5),
TimeStepping with SICONOS_TS_LINEAR (one contact solve per step), warm start from the
last step's impulses in both (Siconos' default keepLambdaAndYState).

Where the formulations differ (state them with the numbers):
* Activation.  Siconos puts a contact in the solve when its predicted gap
  y + h/2 y' <= 0 and applies u_n+ >= -e u_n- (velocity level, no gap term): a contact
  may be stopped before it touches or after it has penetrated, and a penetration is
  never pushed out (it drifts).  graindyn solves every contact closer than 0.1 R with
  u_n+ >= -max(g, 0)/(theta dt), and the Newton bound only on impacting contacts.
* Tolerance.  Siconos (LIGHT_WITH_FULL_FINAL, its default): ||P^k - P^(k-1)||_2 /
  ||P^k||_2 < tol, then the natural-map residual of the whole problem over
  max(||P||, ||u||, ||q||) (impulses and velocities in one norm, so unit dependent)
  must be < tol too, else the sweeps go on with a smaller increment tolerance.
  graindyn: sum |P^k - P^(k-1)| / sum |P^k| <= tol and the Signorini violation over a
  velocity scale <= tol.  Sweep counts are therefore not strictly like for like.
* The 3D local solver: Siconos' default for FC3D NSGS is a Newton solve per contact
  (ONECONTACT_NSN_GP_HYBRID), graindyn's a closed-form projection (diagonal local
  Delassus operator of spheres); in 2D both solve each contact exactly.
* Theta enters Siconos' force integration too; with constant gravity that changes
  nothing, so the two steps are the same trapezoidal rule in free flight.

Timings are wall-clock per step after a warm-up (graindyn's numba compilation is done
on a throwaway engine first); Siconos' time is given without and with its Python-side
contact detection.  On a shared machine they are noisy.
"""
import argparse
import os
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

for _name in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ[_name] = "1"

import numpy as np  # noqa: E402

RADIUS = 1e-3                # mean grain radius [m]
DENSITY = 2650.0             # [kg/m^3] (spheres), [kg/m^2] (disks)
G = 9.81                     # [m/s^2]
DT = 1e-4                    # [s]
THETA = 0.5

COLUMN_GRAINS = 10
COLUMN_RESTITUTION = 0.5
COLUMN_FRICTION = 0.4
COLUMN_STEPS = 200
COLUMN_TOLERANCES = (1e-4, 1e-10)
COLUMN_MAX_SWEEPS = 100_000

PILE_COLUMNS, PILE_ROWS = 20, 10
PILE_PITCH = 2.4 * RADIUS    # lattice pitch [m]
PILE_SPREAD = 0.05           # radii uniform in RADIUS (1 +- PILE_SPREAD)
PILE_JITTER = 0.05 * RADIUS  # lattice offsets uniform in +-PILE_JITTER [m]
PILE_RESTITUTION = 0.3
PILE_FRICTION = 0.4
PILE_TOLERANCE = 1e-4
PILE_MAX_SWEEPS = 1000
PILE_STEPS = 1500
PILE_CHECKPOINTS = (25, 50, 100, 150, 200, 300, 500, 1000)   # steps, positions compared
PILE_SEED = 2024
SKIN = 0.3 * RADIUS          # Siconos candidate pairs and walls: gap below this [m]

SICONOS_HINT = ("Siconos is not importable by {python}: install it with\n"
                "    apt-get install -y python3-siconos\n"
                "(Debian's Siconos 4.4 for /usr/bin/python3) or give another interpreter "
                "with --siconos-python PATH.")


class Stopwatch:
    """The wall-clock and CPU time [s] (wall, cpu) summed over the blocks it times:
    ``with watch: ...``."""

    def __init__(self):
        self.wall = self.cpu = 0.0

    def __enter__(self):
        self._wall, self._cpu = time.perf_counter(), time.process_time()
        return self

    def __exit__(self, *exc):
        self.wall += time.perf_counter() - self._wall
        self.cpu += time.process_time() - self._cpu

    def per_step(self, steps):
        """{"step_time": wall, "step_cpu": cpu} per step [s]."""
        return {"step_time": self.wall / steps, "step_cpu": self.cpu / steps}


# ---------------------------------------------------------------- the problems
def column_setup():
    """Heights (N,) [m] of the column's sphere centres, touching, the lowest on z = 0."""
    return RADIUS * (1.0 + 2.0 * np.arange(COLUMN_GRAINS))


def pile_setup():
    """(positions (N, 2) [m], radii (N,) [m], box width [m]) of the pile's lattice."""
    rng = np.random.default_rng(PILE_SEED)
    grid = np.stack(np.meshgrid(np.arange(PILE_COLUMNS), np.arange(PILE_ROWS)),
                    -1).reshape(-1, 2)
    positions = (grid + 0.5) * PILE_PITCH + rng.uniform(-PILE_JITTER, PILE_JITTER,
                                                        grid.shape)
    radii = RADIUS * rng.uniform(1.0 - PILE_SPREAD, 1.0 + PILE_SPREAD, len(grid))
    return positions, radii, PILE_COLUMNS * PILE_PITCH


def pile_walls(width):
    """The pile's walls as lines A x + B y + C = 0: floor, left, right."""
    return np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, -width]])


# ---------------------------------------------------------------- graindyn half
def graindyn_column(heights, tolerance):
    """graindyn's column run: dict of forces_below (N,) [N], heights (N,) [m],
    mean_sweeps, not_converged, step_time and step_cpu [s] (wall-clock, CPU)."""
    import graindyn as gd
    from graindyn.engines.contact_dynamics.engine import ContactDynamics

    def build():
        positions = np.zeros((heights.size, 3))
        positions[:, 2] = heights
        state = gd.State.create(positions, np.full(heights.size, RADIUS), DENSITY, dim=3)
        material = gd.Material(restitution=COLUMN_RESTITUTION,
                               friction_static=COLUMN_FRICTION,
                               friction_sliding=COLUMN_FRICTION)
        return ContactDynamics(state, [material], walls=[gd.Plane((0, 0, 0), (0, 0, 1))],
                               gravity=(0.0, 0.0, -G), dt=DT, theta=THETA,
                               tolerance=tolerance, max_iterations=COLUMN_MAX_SWEEPS)

    build().run(steps=5)                                   # numba compilation
    engine = build()
    watch = Stopwatch()
    with warnings.catch_warnings(), watch:
        warnings.simplefilter("ignore", RuntimeWarning)
        engine.run(steps=COLUMN_STEPS)
    forces = np.zeros(heights.size)
    pairs = engine.contacts()
    forces[np.maximum(pairs.i, pairs.j)] = pairs.normal_force
    forces[0] = engine.wall_contacts().normal_force.sum()
    return {"forces_below": forces, "heights": engine.state.positions[:, 2].copy(),
            "mean_sweeps": engine.mean_iterations, "not_converged": engine.not_converged,
            **watch.per_step(COLUMN_STEPS)}


def graindyn_pile(positions, radii, width):
    """graindyn's pile run: dict of checkpoints (K, N, 2) [m], positions (N, 2),
    velocities (N, 3) (vx, vy, spin), pair_forces (M,) [N] of the M force-carrying
    grain pairs, floor_force [N] (normal), wall_vertical [N] (of all walls on the
    grains), wall_contacts, mean_sweeps, not_converged, step_time and step_cpu [s]."""
    import graindyn as gd
    from graindyn.engines.contact_dynamics.engine import ContactDynamics

    def build():
        state = gd.State.create(positions, radii, DENSITY, dim=2)
        material = gd.Material(restitution=PILE_RESTITUTION, friction_static=PILE_FRICTION,
                               friction_sliding=PILE_FRICTION)
        walls = gd.box((0.0, 0.0), (width, 100 * width), dim=2)   # xlo, xhi, ylo
        return ContactDynamics(state, [material], walls=walls, gravity=(0.0, -G, 0.0),
                               dt=DT, theta=THETA, tolerance=PILE_TOLERANCE,
                               max_iterations=PILE_MAX_SWEEPS)

    build().run(steps=50)                                  # numba compilation
    engine = build()
    floor = [w.name for w in engine.walls.walls].index("ylo")
    checkpoints, done, watch = [], 0, Stopwatch()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        for step in (*PILE_CHECKPOINTS, PILE_STEPS):
            with watch:
                engine.run(steps=step - done)
            done = step
            checkpoints.append(engine.state.positions[:, :2].copy())
    s = engine.state
    pairs = engine.contacts()
    walls = engine.wall_contacts()
    vertical = walls.normal_force * walls.normal[:, 1] + walls.tangential_force[:, 1]
    return {"checkpoints": np.array(checkpoints[:-1]), "positions": checkpoints[-1],
            "velocities": np.column_stack([s.velocities[:, :2],
                                           s.angular_velocities[:, 2]]),
            "pair_forces": pairs.normal_force,
            "floor_force": walls.normal_force[walls.wall == floor].sum(),
            "wall_vertical": vertical.sum(), "wall_contacts": walls.grain.size,
            "mean_sweeps": engine.mean_iterations, "not_converged": engine.not_converged,
            **watch.per_step(PILE_STEPS)}


# ---------------------------------------------------------------- Siconos half
def siconos_solver(dimension, tolerance, max_sweeps):
    """A FrictionContact problem of ``dimension`` with NSGS and its SolverOptions."""
    import siconos.kernel as sk
    import siconos.numerics as sn

    solver = sn.SICONOS_FRICTION_2D_NSGS if dimension == 2 else sn.SICONOS_FRICTION_3D_NSGS
    problem = sk.FrictionContact(dimension, solver)
    options = problem.numericsSolverOptions()
    options.dparam[sn.SICONOS_DPARAM_TOL] = tolerance
    options.iparam[sn.SICONOS_IPARAM_MAX_ITER] = max_sweeps
    return problem, options


def siconos_step(simulation, problem, options, tolerance):
    """One Siconos step: (sweeps, did not converge) of its contact solve (0, False
    without active contacts, when the solver is not called)."""
    import siconos.numerics as sn

    simulation.computeOneStep()
    if problem.getSizeOutput() > 0:
        sweeps = int(options.iparam[sn.SICONOS_IPARAM_ITER_DONE])
        failed = bool(options.dparam[sn.SICONOS_DPARAM_RESIDU] > tolerance)
    else:
        sweeps, failed = 0, False
    simulation.nextStep()
    return sweeps, failed


def siconos_column(heights, tolerance):
    """Siconos' column run, the dict of graindyn_column."""
    import siconos.kernel as sk

    n = heights.size
    mass = 4.0 / 3.0 * np.pi * DENSITY * RADIUS**3
    inertia = 0.4 * mass * RADIUS**2
    system = sk.NonSmoothDynamicalSystem(0.0, 10.0)
    spheres = []
    for z in heights:
        sphere = sk.LagrangianLinearTIDS(np.array([0.0, 0.0, z, 0.0, 0.0, 0.0]), np.zeros(6),
                                         np.diag([mass, mass, mass, inertia, inertia,
                                                  inertia]))
        sphere.setFExtPtr(np.array([0.0, 0.0, -mass * G, 0.0, 0.0, 0.0]))
        system.insertDynamicalSystem(sphere)
        spheres.append(sphere)
    law = sk.NewtonImpactFrictionNSL(COLUMN_RESTITUTION, 0.0, COLUMN_FRICTION, 3)

    def rows(offset):
        """Normal and tangential (x, y) velocity rows of a contact point at offset
        ``offset`` along z from the centre: v + w x (offset e_z)."""
        h = np.zeros((3, 6))
        h[0, 2] = h[1, 0] = h[2, 1] = 1.0
        h[1, 4], h[2, 3] = offset, -offset
        return h

    contacts = [sk.Interaction(law, sk.LagrangianLinearTIR(rows(-RADIUS),
                                                           np.array([-RADIUS, 0.0, 0.0])))]
    system.link(contacts[0], spheres[0])
    for k in range(1, n):             # lower sphere k - 1, upper k, normal +z
        h = np.hstack([-rows(RADIUS), rows(-RADIUS)])
        contact = sk.Interaction(law, sk.LagrangianLinearTIR(h, np.array([-2 * RADIUS, 0.0,
                                                                          0.0])))
        system.link(contact, spheres[k - 1], spheres[k])
        contacts.append(contact)
    problem, options = siconos_solver(3, tolerance, COLUMN_MAX_SWEEPS)
    simulation = sk.TimeStepping(system, sk.TimeDiscretisation(0.0, DT),
                                 sk.MoreauJeanOSI(THETA), problem)
    simulation.setNewtonOptions(sk.SICONOS_TS_LINEAR)
    sweeps, failed, watch = [], 0, Stopwatch()
    with watch:
        for _ in range(COLUMN_STEPS):
            done, bad = siconos_step(simulation, problem, options, tolerance)
            sweeps.append(done)
            failed += bad
    return {"forces_below": np.array([c.lambda_(1)[0] / DT for c in contacts]),
            "heights": np.array([s.q()[2] for s in spheres]),
            "mean_sweeps": float(np.mean(sweeps)), "not_converged": failed,
            **watch.per_step(COLUMN_STEPS)}


class SiconosPile:
    """The pile in Siconos: Disks, DiskDiskR and DiskPlanR interactions for the pairs
    and grain-wall contacts closer than SKIN, rebuilt when a disk has moved SKIN / 4."""

    def __init__(self, positions, radii, width):
        import siconos.kernel as sk
        from siconos.mechanics.collision.bodies import Disk

        self.sk = sk
        self.radii = radii
        self.walls = pile_walls(width)
        masses = np.pi * DENSITY * radii**2
        system = sk.NonSmoothDynamicalSystem(0.0, 10.0)
        self.disks = []
        for (x, y), r, m in zip(positions, radii, masses):
            disk = Disk(r, m, np.array([x, y, 0.0]), np.zeros(3))
            disk.setFExtPtr(np.array([0.0, -m * G, 0.0]))
            system.insertDynamicalSystem(disk)
            self.disks.append(disk)
        self.law = sk.NewtonImpactFrictionNSL(PILE_RESTITUTION, 0.0, PILE_FRICTION, 2)
        self.problem, self.options = siconos_solver(2, PILE_TOLERANCE, PILE_MAX_SWEEPS)
        self.simulation = sk.TimeStepping(system, sk.TimeDiscretisation(0.0, DT),
                                          sk.MoreauJeanOSI(THETA), self.problem)
        self.simulation.setNewtonOptions(sk.SICONOS_TS_LINEAR)
        self.first, self.second = np.triu_indices(radii.size, 1)
        self.pairs, self.wall_contacts = {}, {}
        self.rebuild(self.positions())

    def positions(self):
        return np.array([disk.q()[:2] for disk in self.disks])

    def velocities(self):
        return np.array([disk.velocity() for disk in self.disks])

    def rebuild(self, positions):
        """Link the candidate pairs and wall contacts of ``positions``, unlink the rest."""
        from siconos.mechanics.collision.bodies import DiskDiskR, DiskPlanR

        i, j = self.first, self.second
        gap = np.hypot(*(positions[i] - positions[j]).T) - self.radii[i] - self.radii[j]
        near = gap < SKIN
        wanted = set(zip(i[near].tolist(), j[near].tolist()))
        a, b, c = self.walls.T
        wall_gap = np.abs(positions[:, :1] * a + positions[:, 1:] * b + c) - self.radii[:, None]
        wanted_walls = set(zip(*np.nonzero(wall_gap < SKIN)))
        for key in [k for k in self.pairs if k not in wanted]:
            self.simulation.unlink(self.pairs.pop(key))
        for key in [k for k in self.wall_contacts if k not in wanted_walls]:
            self.simulation.unlink(self.wall_contacts.pop(key))
        for p, q in sorted(wanted - self.pairs.keys()):
            contact = self.sk.Interaction(self.law, DiskDiskR(self.radii[p], self.radii[q]))
            self.simulation.link(contact, self.disks[p], self.disks[q])
            self.pairs[(p, q)] = contact
        for g, w in sorted(wanted_walls - self.wall_contacts.keys()):
            # the 7-argument constructor: width infinite (the 4-argument one leaves the
            # width uninitialised in Siconos 4.4)
            contact = self.sk.Interaction(self.law, DiskPlanR(self.radii[g], *self.walls[w],
                                                              0.0, 0.0, np.inf))
            self.simulation.link(contact, self.disks[g])
            self.wall_contacts[(g, w)] = contact
        self.built_at = positions

    def run(self):
        """The dict of graindyn_pile, plus detection_time (wall-clock) [s] per step."""
        checkpoints, sweeps, failed = [], [], 0
        detection, stepping = Stopwatch(), Stopwatch()
        for step in range(1, PILE_STEPS + 1):
            with detection:
                positions = self.positions()
                if np.abs(positions - self.built_at).max() > SKIN / 4:
                    self.rebuild(positions)
            with stepping:
                done, bad = siconos_step(self.simulation, self.problem, self.options,
                                         PILE_TOLERANCE)
            sweeps.append(done)
            failed += bad
            if step in PILE_CHECKPOINTS:
                checkpoints.append(self.positions())
        positions = self.positions()
        pair_forces = np.array([c.lambda_(1)[0] / DT for c in self.pairs.values()])
        floor_force = wall_vertical = 0.0
        wall_contacts = 0
        for (g, w), contact in self.wall_contacts.items():
            impulse = np.asarray(contact.lambda_(1))
            if impulse[0] <= 0:
                continue
            a, b, c = self.walls[w]
            side = np.sign(a * positions[g, 0] + b * positions[g, 1] + c) / np.hypot(a, b)
            wall_vertical += side * (impulse[0] * b + impulse[1] * a) / DT
            floor_force += impulse[0] / DT if w == 0 else 0.0
            wall_contacts += 1
        return {"checkpoints": np.array(checkpoints), "positions": positions,
                "velocities": self.velocities(), "pair_forces": pair_forces[pair_forces > 0],
                "floor_force": floor_force,
                "wall_vertical": wall_vertical, "wall_contacts": wall_contacts,
                "mean_sweeps": float(np.mean(sweeps)), "not_converged": failed,
                **stepping.per_step(PILE_STEPS),
                "detection_time": detection.wall / PILE_STEPS}


def siconos_worker(folder):
    """The Siconos half: read folder/setup.npz, write folder/siconos.npz."""
    setup = np.load(folder / "setup.npz")
    results = {}
    for tolerance in COLUMN_TOLERANCES:
        for key, value in siconos_column(setup["heights"], tolerance).items():
            results[f"column_{tolerance:g}/{key}"] = value
    pile = SiconosPile(setup["positions"], setup["radii"], float(setup["width"]))
    for key, value in pile.run().items():
        results[f"pile/{key}"] = value
    np.savez(folder / "siconos.npz", **results)


def run_siconos(python, heights, positions, radii, width):
    """The Siconos results (dict of the worker's arrays), or exit with the error."""
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        np.savez(folder / "setup.npz", heights=heights, positions=positions, radii=radii,
                 width=width)
        out = subprocess.run([python, str(Path(__file__).resolve()), "--siconos-worker",
                              str(folder)], capture_output=True, text=True)
        if out.returncode != 0:
            sys.exit(f"the Siconos run failed:\n{out.stdout[-3000:]}\n{out.stderr[-3000:]}")
        with np.load(folder / "siconos.npz") as data:
            return {k: data[k] for k in data.files}


# ---------------------------------------------------------------- comparison
def overlap(positions, radii, width):
    """The largest overlap [m] of the disks with each other and with the walls."""
    i, j = np.triu_indices(radii.size, 1)
    pair = radii[i] + radii[j] - np.hypot(*(positions[i] - positions[j]).T)
    a, b, c = pile_walls(width).T
    wall = radii[:, None] - np.abs(positions[:, :1] * a + positions[:, 1:] * b + c)
    return max(pair.max(), wall.max(), 0.0)


def pile_statistics(result, radii, width):
    """The end-state numbers of a pile run (dict)."""
    positions = result["positions"]
    weight = np.pi * DENSITY * (radii**2).sum() * G
    mean_height = positions[:, 1].mean()
    speed = np.hypot(result["velocities"][:, 0], result["velocities"][:, 1])
    return {"phi": np.pi * (radii**2).sum() / (2.0 * width * mean_height),
            "mean_height": mean_height / RADIUS,
            "top": (positions[:, 1] + radii).max() / RADIUS,
            "coordination": 2.0 * len(result["pair_forces"]) / radii.size,
            "wall_contacts": int(result["wall_contacts"]),
            "floor": result["floor_force"] / weight,
            "walls": result["wall_vertical"] / weight,
            "max_speed": speed.max(), "mean_speed": speed.mean(),
            "overlap": overlap(positions, radii, width) / RADIUS}


def markdown_tables(column, pile, divergence):
    """The report's markdown: column table, pile table, divergence table."""
    lines = [f"### 1. Column of {COLUMN_GRAINS} spheres on a floor ({COLUMN_STEPS} steps, "
             "at rest from touching)",
             "",
             "| tolerance | code | wall / CPU time per step [us] | sweeps/step | "
             "steps not converged | max abs(F_k / W_above - 1) | floor / weight | "
             "max penetration / R | max abs(z - z_other) / R |",
             "|---|---|---|---|---|---|---|---|---|"]
    lines += [f"| {tol:g} | {code} | {r['step_time'] * 1e6:.0f} / {r['step_cpu'] * 1e6:.0f} | "
              f"{r['mean_sweeps']:.1f} | "
              f"{r['not_converged']} | {r['force_error']:.1e} | {r['floor']:.10f} | "
              f"{r['penetration']:.1e} | {r['height_difference']:.1e} |"
              for tol, code, r in column]
    lines += ["", f"### 2. Pile of {PILE_COLUMNS * PILE_ROWS} disks settling in a box "
              f"({PILE_STEPS} steps = {PILE_STEPS * DT:g} s)", "",
              "| code | wall / CPU time per step [ms] | sweeps/step | steps not converged | "
              "phi | <y> / R | top / R | z (grain-grain) | wall contacts | "
              "floor N / weight | walls vertical / weight | mean / max speed [m/s] | "
              "max overlap / R |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for code, r, s in pile:
        timing = f"{r['step_time'] * 1e3:.2f} / {r['step_cpu'] * 1e3:.2f}"
        if "detection_time" in r:
            timing += f" (+{r['detection_time'] * 1e3:.2f} detection)"
        lines.append(f"| {code} | {timing} | {r['mean_sweeps']:.0f} | {r['not_converged']} "
                     f"| {s['phi']:.4f} | {s['mean_height']:.3f} | {s['top']:.2f} | "
                     f"{s['coordination']:.3f} | {s['wall_contacts']} | {s['floor']:.4f} | "
                     f"{s['walls']:.4f} | {s['mean_speed']:.1e} / {s['max_speed']:.1e} | "
                     f"{s['overlap']:.1e} |")
    lines += ["", "### 2b. Pile, grain by grain: graindyn against Siconos", "",
              "| step | time [s] | max abs(dr) / R | median abs(dr) / R | "
              "grains with abs(dr) > 0.1 R |", "|---|---|---|---|---|"]
    lines += [f"| {step} | {step * DT:.4f} | {big:.2e} | {median:.2e} | {count} |"
              for step, big, median, count in divergence]
    return "\n".join(lines)


def compare(gd_columns, sic, positions, radii, width, gd_pile):
    """Print and return the markdown tables of the graindyn and Siconos results."""
    column = []
    mass = 4.0 / 3.0 * np.pi * DENSITY * RADIUS**3
    above = mass * G * np.arange(COLUMN_GRAINS, 0, -1)
    for tolerance, mine in zip(COLUMN_TOLERANCES, gd_columns):
        theirs = {k.split("/")[1]: v for k, v in sic.items()
                  if k.startswith(f"column_{tolerance:g}/")}
        for code, r, other in (("graindyn", mine, theirs), ("Siconos", theirs, mine)):
            gaps = np.diff(np.concatenate([[-RADIUS], r["heights"]])) - 2 * RADIUS
            column.append((tolerance, code, {
                **r, "force_error": np.abs(r["forces_below"] / above - 1).max(),
                "floor": r["forces_below"][0] / above[0],
                "penetration": max(-gaps.min(), 0.0) / RADIUS,
                "height_difference": np.abs(r["heights"] - other["heights"]).max() / RADIUS}))
    sic_pile = {k.split("/")[1]: v for k, v in sic.items() if k.startswith("pile/")}
    pile = [(code, r, pile_statistics(r, radii, width))
            for code, r in (("graindyn", gd_pile), ("Siconos", sic_pile))]
    divergence = []
    for step, mine, theirs in zip(PILE_CHECKPOINTS, gd_pile["checkpoints"],
                                  sic_pile["checkpoints"]):
        distance = np.hypot(*(mine - theirs).T) / RADIUS
        divergence.append((step, distance.max(), np.median(distance),
                           int((distance > 0.1).sum())))
    return markdown_tables(column, pile, divergence)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--siconos-python", default="/usr/bin/python3",
                        help="the interpreter that imports siconos (default /usr/bin/python3)")
    parser.add_argument("--markdown", type=Path, help="also write the tables to this file")
    parser.add_argument("--siconos-worker", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.siconos_worker is not None:
        siconos_worker(args.siconos_worker)
        return
    check = subprocess.run([args.siconos_python, "-c",
                            "import siconos.kernel, siconos.mechanics.collision.bodies"],
                           capture_output=True, text=True)
    if check.returncode != 0:
        sys.exit(SICONOS_HINT.format(python=args.siconos_python) + "\n" + check.stderr)
    heights = column_setup()
    positions, radii, width = pile_setup()
    start = time.perf_counter()
    gd_columns = [graindyn_column(heights, tolerance) for tolerance in COLUMN_TOLERANCES]
    gd_pile = graindyn_pile(positions, radii, width)
    middle = time.perf_counter()
    sic = run_siconos(args.siconos_python, heights, positions, radii, width)
    end = time.perf_counter()
    text = compare(gd_columns, sic, positions, radii, width, gd_pile)
    text += (f"\n\nWall time of the whole comparison: graindyn half {middle - start:.0f} s, "
             f"Siconos half {end - middle:.0f} s.\n")
    print(text)
    if args.markdown is not None:
        args.markdown.write_text(text)


if __name__ == "__main__":
    main()
