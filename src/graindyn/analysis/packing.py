"""Packing fraction, void ratio and coordination number."""
import numpy as np


def slab_volumes(state, lo, hi, axis=None):
    """Volume [m^3] (2D: area [m^2]) of each grain inside the slab lo <= x_axis <= hi [m].

    Exact cap volumes pi (R^2 u - (u^3)/3) between the cut planes (3D), segment areas (2D);
    axis defaults to the vertical (z in 3D, y in 2D).
    """
    axis = (2 if state.dim == 3 else 1) if axis is None else axis
    c = state.positions[:, axis]
    r = state.radii
    a = np.clip(lo - c, -r, r)
    b = np.clip(hi - c, -r, r)
    if state.dim == 3:
        prim = lambda u: np.pi * (r**2 * u - u**3 / 3.0)
    else:
        prim = lambda u: u * np.sqrt(np.maximum(r**2 - u**2, 0)) + r**2 * np.arcsin(u / r)
    return prim(b) - prim(a)


def packing_fraction(state, cross_section, lo, hi, axis=None):
    """Solid fraction in the slab [lo, hi] of a container of ``cross_section`` area
    [m^2] (2D: width [m]) along ``axis``; grains cut by the slab count partially."""
    if not hi > lo or not cross_section > 0:
        raise ValueError("packing_fraction needs hi > lo and a positive cross-section")
    return float(slab_volumes(state, lo, hi, axis).sum() / (cross_section * (hi - lo)))


def void_ratio(packing):
    """e = (V - V_s)/V_s = (1 - phi)/phi."""
    return (1.0 - packing) / packing


def coordination_number(engine, exclude_rattlers=False):
    """Mean number of grain-grain contacts per free grain of ``engine`` (core.engine),
    Z = (2 C + C_images) / N: with symmetry planes (core/symmetry.py) each contact of a
    grain with a mirror image counts one for its grain, as the contact of the full
    system it stands for counts one for each of its two grains.

    exclude_rattlers: leave out grains with fewer than 2 contacts (walls counted), and
    the contacts they carry, as is usual for the mechanical coordination number (an
    image contact stays with its grain; the image of a rattler is not dropped).
    """
    pairs = engine.contacts()
    i, j = pairs.i, pairs.j
    n = engine.state.n
    free = engine.state.fixed == 0
    imaged = engine.image_contacts().grain if hasattr(engine, "image_contacts") \
        else np.zeros(0, np.int64)
    if not exclude_rattlers:
        return float((2 * i.size + imaged.size) / max(1, int(free.sum())))
    gi = engine.wall_contacts().grain
    keep = free.copy()
    while True:
        count = np.bincount(i[keep[i] & keep[j]], minlength=n) \
            + np.bincount(j[keep[i] & keep[j]], minlength=n) + np.bincount(gi, minlength=n) \
            + np.bincount(imaged, minlength=n)
        drop = keep & (count < 2)
        if not drop.any():
            break
        keep &= ~drop
    both = keep[i] & keep[j]
    return float((2 * both.sum() + keep[imaged].sum()) / max(1, int(keep.sum())))
