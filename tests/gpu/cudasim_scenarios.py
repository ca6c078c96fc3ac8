"""Run by tests/gpu/test_cudasim.py under NUMBA_ENABLE_CUDASIM=1: short collision
scenarios (grain on grain, oblique and spinning; grain on a plane, sliding) for every
normal, damping, tangential, rolling and twisting law and every integrator, in 3D and
2D, on backend "cpu" and backend "gpu".  Prints one JSON line per scenario: the largest
relative difference of the final state between the backends, the restitution of the
head-on pair on each backend, and the steps in contact."""
import json
import sys

import numpy as np

import graindyn as gd
from graindyn.analysis.energy import energy_budget

SCENARIOS = [
    (("hooke", "linear", "cundall_strack", "none", "none"), "velocity_verlet", 3),
    (("hertz", "viscoelastic", "mindlin", "constant", "constant"), "gear6", 3),
    (("hertz", "tsuji", "coulomb", "epsd", "epsd"), "beeman", 3),
    (("hertz", "karrech", "karrech", "none", "none"), "velocity_verlet", 3),
    (("hertz", "viscoelastic", "oquendo", "none", "oquendo"), "optimized_velocity_verlet",
     3),
    (("walton_braun", "none", "coulomb", "none", "none"), "verlet", 2),
    (("hooke", "linear", "mindlin", "constant", "none"), "leap_frog", 2),
    (("hertz", "tsuji", "cundall_strack", "none", "none"), "gear3", 3),
    (("hertz", "none", "coulomb", "none", "none"), "velocity_verlet_plain", 3),
]
MATERIAL = dict(youngs_modulus=1e7, restitution=0.7, kn=2e3, kt=1e3, friction_sliding=0.4,
                friction_static=0.5, friction_rolling=0.05, friction_twisting=0.05,
                gamma_n=2e5, gamma_nt=1e3, slip_threshold=1e-4, alpha_n=0.44, alpha_t=0.44,
                rolling_stiffness=1.0, rolling_damping=1e-4, twisting_stiffness=1e-4,
                twisting_damping=1e-8, tangential_damping=0.1)


def make(model, integrator, dim, backend):
    r = 1e-3
    pos = [[0.0, 0.0, 3e-3], [2.02e-3, 0.3e-3, 3e-3], [6e-3, 0.0, 1.01e-3]]
    vel = [[0.5, 0.0, 0.0], [-0.5, 0.0, 0.0], [0.3, 0.0, -0.2]]
    spin = [[0.0, 0.0, 40.0], [0.0, 0.0, -20.0], [0.0, 0.0, 30.0]]
    if dim == 2:       # disks in the x-y plane, the plane y = 0 below them
        pos = [[p[0], p[2]] for p in pos]
        vel = [[v[0], v[2], 0.0] for v in vel]
        spin = [[0.0, 0.0, w[2]] for w in spin]
        plane = gd.Plane((0, 0, 0), (0, 1, 0))
        gravity = (0.0, -9.81, 0.0)
    else:
        plane = gd.Plane((0, 0, 0), (0, 0, 1))
        gravity = (0.0, 0.0, -9.81)
    density = 2650.0 if dim == 3 else 2650.0 * 2e-3
    state = gd.State.create(np.array(pos), np.full(3, r), density, dim=dim,
                            velocities=np.array(vel))
    state.angular_velocities[:] = spin
    return gd.Simulation(state, [gd.Material(**MATERIAL)], gd.ContactModel(*model),
                         walls=[plane], gravity=gravity, integrator=integrator,
                         check_interval=50, backend=backend)


def main(steps):
    for model, integrator, dim in SCENARIOS:
        runs = {}
        for backend in ("cpu", "gpu"):
            sim = make(model, integrator, dim, backend)
            contact = 0
            for _ in range(steps // 10):
                sim.run(steps=10)
                contact += int(len(sim.contacts()[0]) > 0)
            runs[backend] = sim
        cpu, gpu = runs["cpu"], runs["gpu"]
        diff = 0.0
        for name in ("positions", "velocities", "angular_velocities", "orientations"):
            a, b = getattr(cpu.state, name), getattr(gpu.state, name)
            diff = max(diff, float(np.abs(a - b).max() / np.abs(a).max()))
        # approach speed 1 m/s along x
        restitution = [float(s.state.velocities[1, 0] - s.state.velocities[0, 0])
                       for s in (cpu, gpu)]
        print(json.dumps({"model": ",".join(model), "integrator": integrator, "dim": dim,
                          "difference": diff, "restitution": restitution,
                          "contact_chunks": contact, "dt": cpu.dt,
                          "energy": [energy_budget(s)["total"] for s in (cpu, gpu)],
                          "dissipated": [sum(s.dissipated.values()) for s in (cpu, gpu)]}),
              flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]))
