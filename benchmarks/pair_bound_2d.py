"""A lower bound on the 2D silo bed's pair forces: the linear law written out by hand.

Imported by ``kernel_times.py silo2d``, which times these loops beside the engine's
pair forces on the same bed, lists and contact state.  One plain loop over the
listed pairs (grain by grain, the CSR lists of Simulation.pairs), each touching
pair's force computed and added to both disks at once, in 2D only (x, y and the spin
about z), with the law's parameters as scalars: no model dispatch, no workspace, no
staging.  Two physics:

``lammps``: what LAMMPS's ``gran/hooke/history`` computes, f_n = k_n delta - m* gamma
v_n, a tangential spring zeta projected onto the tangent plane (its length not kept),
grown by v_t dt and capped at mu |f_n| (zeta reset to the capped force); no
energies, no per-pair force kept.

``graindyn``: what graindyn's ``hooke`` + ``linear`` + ``cundall_strack`` computed
for each 2D contact while its springs were vectors in 2D too: the dashpot
2 beta sqrt(k_n m*), the spring rotated onto the tangent plane with its length kept
(the engine now keeps the same spring as a scalar along the tangent, Perez Eq. 20,
physics/tangential.py), the normal and tangential energy dissipated, the largest
overlap / smaller radius, the touching mark and the force kept per pair.

Measurement code only: the engine never calls it, and no test compares its forces
(they differ from the engine's in the order of the sums).
"""
import math

import numba
import numpy as np


@numba.njit(error_model="numpy", inline="always")
def _pairs(full, start, partners, positions, velocities, spins, radii, masses, history, ht,
           pair_force, force, kn, kt, beta, gamma_n, mu, dt):
    lost_n = 0.0
    lost_t = 0.0
    worst = 0.0
    started = 0
    mark = history.shape[1] - 1
    for i in range(force.shape[0]):
        force[i, 0] = 0.0
        force[i, 1] = 0.0
        force[i, 2] = 0.0
    for i in range(force.shape[0]):
        xi = positions[i, 0]
        yi = positions[i, 1]
        r_i = radii[i]
        m_i = masses[i]
        for k in range(start[i], start[i + 1]):
            j = partners[k]
            dx = xi - positions[j, 0]
            dy = yi - positions[j, 1]
            rsum = r_i + radii[j]
            d2 = dx * dx + dy * dy
            if d2 >= rsum * rsum:
                history[k, ht] = 0.0
                history[k, ht + 1] = 0.0
                continue
            dist = math.sqrt(d2)
            inv = 1.0 / dist
            nx = dx * inv
            ny = dy * inv
            overlap = rsum - dist
            m_eff = m_i * masses[j] / (m_i + masses[j])
            if full:
                share = overlap / rsum
                lever_i = r_i - share * radii[j]
                lever_j = radii[j] - share * r_i
                worst = max(worst, overlap / min(r_i, radii[j]))
            else:
                lever_i = r_i - 0.5 * overlap
                lever_j = radii[j] - 0.5 * overlap
            w = lever_i * spins[i, 2] + lever_j * spins[j, 2]
            vx = velocities[i, 0] - velocities[j, 0] + w * ny
            vy = velocities[i, 1] - velocities[j, 1] - w * nx
            vn = vx * nx + vy * ny
            c = 2.0 * beta * math.sqrt(kn * m_eff) if full else m_eff * gamma_n
            f_el = kn * overlap
            fn = f_el - c * vn
            cap = abs(fn)
            tx = vx - vn * nx
            ty = vy - vn * ny
            zx = history[k, ht]
            zy = history[k, ht + 1]
            old = zx * zx + zy * zy
            zn = zx * nx + zy * ny
            zx -= zn * nx
            zy -= zn * ny
            if full and old > 0.0:
                new = zx * zx + zy * zy
                if new > 0.0:
                    scale = math.sqrt(old / new)
                    zx *= scale
                    zy *= scale
            zx += tx * dt
            zy += ty * dt
            ftx = -kt * zx
            fty = -kt * zy
            f2 = ftx * ftx + fty * fty
            limit = mu * cap
            if f2 > limit * limit:
                s = limit / math.sqrt(f2)
                ftx *= s
                fty *= s
                zx = -ftx / kt
                zy = -fty / kt
            history[k, ht] = zx
            history[k, ht + 1] = zy
            fx = fn * nx + ftx
            fy = fn * ny + fty
            if full:
                lost_n += (fn - f_el) * -vn * dt
                lost_t += -(ftx * tx + fty * ty) * dt - 0.5 * kt * (zx * zx + zy * zy - old)
                started += history[k, mark] == 0.0
                history[k, mark] = 1.0
                pair_force[k, 0] = fx
                pair_force[k, 1] = fy
            couple = nx * fty - ny * ftx
            force[i, 0] += fx
            force[i, 1] += fy
            force[i, 2] -= lever_i * couple
            force[j, 0] -= fx
            force[j, 1] -= fy
            force[j, 2] -= lever_j * couple
    return lost_n + lost_t + worst + started


@numba.njit(error_model="numpy")
def lammps_physics(start, partners, positions, velocities, spins, radii, masses, history, ht,
                   pair_force, force, kn, kt, beta, gamma_n, mu, dt):
    """The loop with LAMMPS's gran/hooke/history physics (module docstring)."""
    return _pairs(False, start, partners, positions, velocities, spins, radii, masses,
                  history, ht, pair_force, force, kn, kt, beta, gamma_n, mu, dt)


@numba.njit(error_model="numpy")
def graindyn_physics(start, partners, positions, velocities, spins, radii, masses, history, ht,
                     pair_force, force, kn, kt, beta, gamma_n, mu, dt):
    """The loop with graindyn's hooke + linear + cundall_strack physics."""
    return _pairs(True, start, partners, positions, velocities, spins, radii, masses,
                  history, ht, pair_force, force, kn, kt, beta, gamma_n, mu, dt)


def loop_arguments(sim, gamma_n):
    """The arguments of both loops for the 2D Simulation ``sim`` (a single material, the
    model hooke + linear + cundall_strack) after its lists were built: its lists,
    grains and a copy of its contact history; gamma_n [1/s] LAMMPS's damping rate."""
    from graindyn.physics.registry import COL, HISTORY, MODES

    s = sim.state
    p = sim.params[0, 0]
    ht = int(sim.model_ids[HISTORY + MODES.index("tangential")])
    return (sim.pairs.start, sim.pairs.partners, s.positions, s.velocities,
            s.angular_velocities, s.radii, s.masses, sim.pairs.history.copy(), ht,
            np.zeros((sim.pairs.partners.size, 3)), np.zeros((s.n, 3)), float(p[COL["kn"]]),
            float(p[COL["kt"]]), float(p[COL["damping_ratio"]]), gamma_n,
            float(p[COL["friction_sliding"]]), sim.dt)
