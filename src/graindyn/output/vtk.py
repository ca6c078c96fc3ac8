"""VTK snapshots that ParaView and OVITO open: one .vtu per snapshot (written by meshio)
and a .pvd time collection per series.

- grains: vertex cells at the centres with point arrays radius [m], velocity [m/s],
  angular_velocity [rad/s], force [N], torque [N m], material [-], fixed [-];
- walls: planes as rectangles spanning the grains' bounding box, cylinders as tubes of
  quads, segments as their rectangles, disks as fans of quads, with cell arrays wall [-] (index) and force [N] (grains on the wall);
- contacts (optional): a line per touching pair, cell arrays normal_force [N] and
  force [N] (on the first grain).
"""
import pathlib
import xml.etree.ElementTree as ET

import meshio
import numpy as np

from ..core.walls import DISK, PLANE, SEGMENT


def grains_mesh(state, marked=None):
    """The grains as a meshio point cloud; ``marked`` (indices) adds the point field
    "marked" (1 for those grains: a silo's blocking arch)."""
    n = state.n
    mesh = meshio.Mesh(
        state.positions.copy(), [("vertex", np.arange(n).reshape(-1, 1))],
        point_data={"radius": state.radii, "velocity": state.velocities,
                    "angular_velocity": state.angular_velocities, "force": state.forces,
                    "torque": state.torques, "material": state.materials.astype(np.int32),
                    "fixed": state.fixed.astype(np.int32)})
    if marked is not None:
        flag = np.zeros(n, np.int32)
        flag[np.asarray(marked, dtype=np.int64)] = 1
        mesh.point_data["marked"] = flag
    return mesh


def write_grains(path, state, marked=None):
    """One VTK file of the grains (grains_mesh) at ``path``."""
    meshio.write(path, grains_mesh(state, marked), binary=True)


def _frame(normal):
    """Two unit vectors spanning the plane normal to ``normal``."""
    helper = np.eye(3)[np.argmin(np.abs(normal))]
    u = np.cross(normal, helper)
    u /= np.linalg.norm(u)
    return u, np.cross(normal, u)


def walls_mesh(walls, lo, hi, segments=48):
    """The walls as quads (planes: a square as wide as the box [lo, hi] [m] around the
    grains; cylinders: a tube between the box's ends along the axis; segments: their
    rectangle, a 2D segment as a strip across z; disks: a fan of ``segments`` quads,
    each with its last corner repeated, around the centre)."""
    points, quads, ids = [], [], []
    centre = 0.5 * (lo + hi)
    size = float(np.linalg.norm(hi - lo)) or 1.0
    for w in range(len(walls)):
        g = walls.geometry[w]
        origin = g[:3] + walls.offset[w]
        axis = g[3:6]
        base = len(points)
        if walls.kind[w] == PLANE:
            foot = centre - np.dot(centre - origin, axis) * axis
            u, v = _frame(axis)
            for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                points.append(foot + 0.5 * size * (su * u + sv * v))
            quads.append([base, base + 1, base + 2, base + 3])
            ids.append(w)
            continue
        if walls.kind[w] == SEGMENT:
            edge = g[7:10]
            if not np.any(edge):          # a 2D segment: a strip one box deep in z
                origin = origin - np.array([0.0, 0.0, 0.5 * size])
                edge = np.array([0.0, 0.0, size])
            points.extend((origin, origin + axis, origin + axis + edge, origin + edge))
            quads.append([base, base + 1, base + 2, base + 3])
            ids.append(w)
            continue
        u, v = _frame(axis)
        if walls.kind[w] == DISK:
            points.append(origin)
            for t in np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False):
                points.append(origin + g[6] * (np.cos(t) * u + np.sin(t) * v))
            for k in range(segments):
                a, b = base + 1 + k, base + 1 + (k + 1) % segments
                quads.append([base, a, b, b])
                ids.append(w)
            continue
        along = [np.dot(lo - origin, axis), np.dot(hi - origin, axis)]
        for t in np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False):
            ring = g[6] * (np.cos(t) * u + np.sin(t) * v)
            points.extend(origin + ring + s * axis for s in (min(along), max(along)))
        for k in range(segments):
            a, b = base + 2 * k, base + 2 * ((k + 1) % segments)
            quads.append([a, b, b + 1, a + 1])
            ids.append(w)
    ids = np.asarray(ids, dtype=np.int32)
    cells = [("quad", np.asarray(quads, dtype=np.int64).reshape(-1, 4))]
    return meshio.Mesh(np.asarray(points, dtype=float).reshape(-1, 3), cells,
                       cell_data={"wall": [ids], "force": [walls.force[ids]]})


def contacts_mesh(engine):
    """Touching pairs of ``engine`` (core.engine) as lines between centres (pairs across
    a periodic boundary are left out: their line would cross the domain)."""
    c = engine.contacts()
    p = engine.state.positions
    direct = np.linalg.norm(p[c.i] - p[c.j], axis=1) \
        < engine.state.radii[c.i] + engine.state.radii[c.j]
    return meshio.Mesh(p.copy(), [("line", np.stack([c.i[direct], c.j[direct]],
                                                    axis=1).reshape(-1, 2))],
                       cell_data={"normal_force": [c.normal_force[direct]],
                                  "force": [c.force[direct]]})


class VtkSeries:
    """The snapshots of a run in ``folder``: ``write(engine)`` adds one of each series
    (grains_000003.vtu: the fourth snapshot) and rewrites the .pvd collections.
    ``entries`` ((number, time [s]) list) is saved in checkpoints, so a resumed run
    drops the snapshots written after its checkpoint."""

    def __init__(self, folder, contacts=False, entries=()):
        self.folder = pathlib.Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.contacts = contacts
        self.entries = [tuple(e) for e in entries]
        self.series = ["grains", "walls"] + (["contacts"] if contacts else [])

    def write(self, engine):
        """Snapshot of the current state (none if one was taken at this time)."""
        s = engine.state
        if self.entries and self.entries[-1][1] == engine.time:
            return
        number = self.entries[-1][0] + 1 if self.entries else 0
        reach = s.radii.max()
        lo = s.positions.min(axis=0) - reach
        hi = s.positions.max(axis=0) + reach
        meshes = {"grains": grains_mesh(s), "walls": walls_mesh(engine.walls, lo, hi)}
        if self.contacts:
            meshes["contacts"] = contacts_mesh(engine)
        for name, mesh in meshes.items():
            if name == "walls" and len(engine.walls) == 0:
                continue
            meshio.write(self.folder / f"{name}_{number:06d}.vtu", mesh, binary=True)
        self.entries.append((number, engine.time))
        self.write_collections()

    def write_collections(self):
        """One .pvd per series listing its snapshots with their times [s]."""
        for name in self.series:
            root = ET.Element("VTKFile", type="Collection", version="0.1")
            coll = ET.SubElement(root, "Collection")
            for number, time in self.entries:
                file = f"{name}_{number:06d}.vtu"
                if (self.folder / file).exists():
                    ET.SubElement(coll, "DataSet", timestep=repr(float(time)), part="0",
                                  file=file)
            ET.ElementTree(root).write(self.folder / f"{name}.pvd", xml_declaration=True)

    def truncate(self, time):
        """Forget (and delete) the snapshots after simulated ``time`` [s] (resuming)."""
        self.entries = [e for e in self.entries if e[1] <= time]
        kept = {number for number, _ in self.entries}
        for path in self.folder.glob("*_*.vtu"):
            if int(path.stem.rsplit("_", 1)[1]) not in kept:
                path.unlink()
        self.write_collections()
