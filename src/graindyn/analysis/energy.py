"""The energy balance of a run [J], from the energies its engine reports
(core.engine.ENERGIES):

    E_kin + E_rot + E_grav + E_elastic + D_normal + D_tangential - W_walls = const.
"""


def energy_budget(engine):
    """Every energy of ``engine.energies()`` [J] and their balance ``total``, constant up
    to the engine's error (kinetic + rotational + gravitational + elastic + dissipated
    - wall work)."""
    out = engine.energies()
    out["total"] = (out["kinetic"] + out["rotational"] + out["gravitational"]
                    + out["elastic"] + out["dissipated_normal"]
                    + out["dissipated_tangential"] - out["wall_work"])
    return out
