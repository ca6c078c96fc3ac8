"""Recompute the viscoelastic-Hertz restitution table of VALIDATION.md a2.

Standalone (numpy + scipy only; does not import graindyn), so it is an
independent check of graindyn.physics.reference.viscoelastic_restitution.

Model: m xi'' = -rho (xi^1.5 + 1.5 A sqrt(xi) xi'), xi(0) = 0, xi'(0) = v
(Brilliantov et al. 1996).  Here the equation is integrated in the
dimensional variables of a concrete (arbitrary) pair and delta is obtained
from delta = A kappa^(2/5) v^(1/5), kappa = (3/2)^(5/2) rho/m; the table
only depends on delta, so any choice of m, rho, v gives the same numbers.
The contact ends when the force reaches zero (clamped, F >= 0) or when the
overlap returns to zero (unclamped).  Integration: scipy LSODA with
rtol 1e-12 and a terminal event, then an independent cross-check with
Radau; the script prints both and their difference.

Usage: python tests/reference/make_viscoelastic_table.py
"""

import numpy as np
from scipy.integrate import solve_ivp
from scipy.special import gamma

# An arbitrary pair (the table depends on delta only).
M = 3.0e-5        # effective mass [kg]
RHO = 1.0e9       # rho = (4/3) E* sqrt(R*) [N m^-1.5]
V = 0.7           # impact speed [m/s]
KAPPA = 1.5 ** 2.5 * RHO / M

C1 = np.sqrt(np.pi) * gamma(0.6) / (2 ** 0.2 * 5 ** 0.4 * gamma(2.1))
C2 = 0.6 * C1 ** 2


def restitution(delta, clamped, method):
    """Integrate the dimensional ODE for a given delta; return -v_end/v."""
    a_visc = delta / (KAPPA ** 0.4 * V ** 0.2)
    x_scale = (M * V * V / RHO) ** 0.4
    t_scale = x_scale / V

    def force(xi, u):
        xi = max(xi, 0.0)
        return RHO * (xi ** 1.5 + 1.5 * a_visc * np.sqrt(xi) * u)

    def rhs(t, y):
        return [y[1], -force(y[0], y[1]) / M]

    if clamped:
        def end(t, y):
            # force / (rho sqrt(xi)); zero at start only through sqrt(xi)
            return y[0] + 1.5 * a_visc * y[1]
    else:
        def end(t, y):
            return y[0]
    end.terminal = True
    end.direction = -1
    sol = solve_ivp(rhs, (0.0, 1e3 * t_scale), [0.0, V], method=method,
                    rtol=1e-12, atol=[1e-14 * x_scale, 1e-14 * V], events=end)
    return -sol.y_events[0][0][1] / V


def main():
    print(f"C1 = {C1:.6f}, C2 = {C2:.6f}")
    print("| delta | eps clamped (F>=0) | eps unclamped | 1-C1 d+C2 d^2 |")
    print("|---|---|---|---|")
    worst = 0.0
    for d in (0.01, 0.05, 0.1, 0.2, 0.3, 0.5):
        ec = restitution(d, True, "LSODA")
        eu = restitution(d, False, "LSODA")
        worst = max(worst, abs(ec - restitution(d, True, "Radau")),
                    abs(eu - restitution(d, False, "Radau")))
        print(f"| {d:g} | {ec:.6f} | {eu:.6f} | {1 - C1 * d + C2 * d * d:.6f} |")
    print(f"max |LSODA - Radau| = {worst:.1e}")


if __name__ == "__main__":
    main()
