"""A picture of a granular packing a person can look at: the grains drawn to scale, the
force network as lines between the centres of touching grains whose width follows the
normal force, grains of interest (a silo's blocking arch) highlighted.  2D as it is;
3D as a vertical slice (the grains cut by the plane y = centre of the bed, drawn as
their cross-sections, and the contacts between them)."""
import numpy as np

from ..core.walls import DISK, PLANE, SEGMENT


def draw_network(engine, path, marked=(), title="", slice_width=None):
    """Write the picture of ``engine`` (core.engine.Engine) to ``path`` (PNG); grains
    ``marked`` are drawn in red.  In 3D only grains whose centre lies within
    ``slice_width`` [m] (default: the largest diameter) of the slice plane are drawn.
    Returns ``path``."""
    from ..figures import subplots
    from matplotlib.collections import EllipseCollection, LineCollection

    s = engine.state
    across, up = 0, (1 if s.dim == 2 else 2)
    shown, cut = section(s, slice_width)
    is_marked = np.zeros(s.n, bool)
    is_marked[np.asarray(marked, dtype=np.int64)] = True
    xy = s.positions[:, [across, up]]
    fig, ax = subplots(figsize=(6, 8))
    colours = np.where(is_marked[shown][:, None], [[0.85, 0.15, 0.1, 1.0]],
                       [[0.8, 0.8, 0.8, 1.0]])
    ax.add_collection(EllipseCollection(2 * cut[shown], 2 * cut[shown], 0.0, units="xy",
                                        offsets=xy[shown], offset_transform=ax.transData,
                                        facecolors=colours, edgecolors="0.5",
                                        linewidths=0.3))
    contacts = engine.contacts()
    both = shown[contacts.i] & shown[contacts.j]
    force = contacts.normal_force[both]
    if force.size and force.max() > 0:
        centre_i = xy[contacts.i[both]]
        # branch_j - branch_i = r_i - r_j (the minimum image across periodic directions)
        centre_j = centre_i - (contacts.branch_j[both] - contacts.branch_i[both])[
            :, [across, up]]
        width = 4.0 * np.clip(force / force.max(), 0.0, 1.0)
        ax.add_collection(LineCollection(np.stack([centre_i, centre_j], axis=1),
                                         linewidths=width, colors="k"))
    lo = (xy[shown] - cut[shown, None]).min(axis=0) if shown.any() else np.zeros(2)
    hi = (xy[shown] + cut[shown, None]).max(axis=0) if shown.any() else np.ones(2)
    margin = 0.05 * float(np.max(hi - lo))
    _draw_walls(ax, engine.walls, across, up, lo - margin, hi + margin)
    ax.set(xlim=(lo[0] - margin, hi[0] + margin), ylim=(lo[1] - margin, hi[1] + margin),
           aspect="equal", xlabel=f"{'xyz'[across]} [m]", ylabel=f"{'xyz'[up]} [m]",
           title=title + ("" if s.dim == 2 else " (vertical slice)")
           + (f"\n{int(is_marked.sum())} grains marked" if is_marked.any() else ""))
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=150)
    return path


def section(state, slice_width=None):
    """(shown (N,) bool, radius drawn (N,) [m]): in 2D every disk at its radius; in 3D
    the spheres cut by the plane y = middle of the bed whose centre lies within
    ``slice_width`` / 2 of it (default: the largest diameter), at the radius of their
    cross-section sqrt(R^2 - dy^2)."""
    if state.dim == 2:
        return np.ones(state.n, bool), state.radii
    y = state.positions[:, 1]
    middle = 0.5 * (y.min() + y.max())
    width = slice_width if slice_width is not None else 2.0 * float(state.radii.max())
    depth = np.abs(y - middle)
    shown = (depth < 0.5 * width) & (depth < state.radii)
    return shown, np.sqrt(np.maximum(state.radii**2 - depth**2, 0.0))


def _draw_walls(ax, walls, across, up, lo, hi):
    """Segments as they are, planes whose normal lies in the picture as lines across it,
    disks whose normal lies in the picture as their diameter (in the picture's axes
    ``across``, ``up``; the view spans lo..hi)."""
    for w in range(len(walls)):
        g = walls.geometry[w]
        origin = g[:3] + walls.offset[w]
        if walls.kind[w] == SEGMENT:
            end = origin + g[3:6]
            ax.plot([origin[across], end[across]], [origin[up], end[up]], color="C0", lw=2)
        elif walls.kind[w] == DISK:      # its diameter in the picture, when it is seen edge-on
            normal = g[3:6][[across, up]]
            size = float(np.linalg.norm(normal))
            if size > 0.99:
                tangent = g[6] * np.array([-normal[1], normal[0]]) / size
                centre = origin[[across, up]]
                ax.plot([centre[0] - tangent[0], centre[0] + tangent[0]],
                        [centre[1] - tangent[1], centre[1] + tangent[1]], color="C0", lw=2)
        elif walls.kind[w] == PLANE:
            normal = g[3:6][[across, up]]
            if abs(normal[0]) > 0.99:
                ax.axvline(origin[across], color="C0", lw=2)
            elif abs(normal[1]) > 0.99:
                ax.axhline(origin[up], color="C0", lw=2)
