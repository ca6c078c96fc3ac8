"""The arch that blocks a jammed silo: the chain of loaded contacts spanning the hole.

The grains and the two walls beside the hole (the lips) are the nodes of a graph whose
edges are the contacts that carry load (normal force above ``loaded`` of the mean);
the arch is the shortest chain from one lip to the other, its length measured centre
to centre (and from the lip's contact point to the first centre).  Any chain that
joins the lips through loaded contacts holds the grains above the hole; the shortest
is the tightest one, the arch the flow would have to break (Pérez Sec. 4 speaks of the
arches above the hole; this is graindyn's operational definition).
"""
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra


def blocking_arch(engine, left, right, loaded=0.01):
    """Indices of the grains of the arch between walls ``left`` and ``right`` (names or
    indices), in order from left to right; an empty array when no chain of loaded
    contacts joins them (the hole is not blocked)."""
    walls = engine.walls
    left, right = walls.index(left), walls.index(right)
    n = engine.state.n
    pairs, wall = engine.contacts(), engine.wall_contacts()
    forces = np.concatenate([pairs.normal_force, wall.normal_force])
    if forces.size == 0 or not np.any(forces > 0):
        return np.array([], dtype=np.int64)
    threshold = loaded * float(np.mean(forces[forces > 0]))
    keep = pairs.normal_force > threshold
    i, j = pairs.i[keep], pairs.j[keep]
    length = np.linalg.norm(pairs.branch_j[keep] - pairs.branch_i[keep], axis=1)
    rows, cols, weights = [i, j], [j, i], [length, length]
    for k, node in ((left, n), (right, n + 1)):
        mine = (wall.wall == k) & (wall.normal_force > threshold)
        g = wall.grain[mine]
        reach = np.linalg.norm(wall.branch[mine], axis=1)
        rows += [g, np.full(g.size, node)]
        cols += [np.full(g.size, node), g]
        weights += [reach, reach]
    graph = coo_matrix((np.concatenate(weights), (np.concatenate(rows),
                                                  np.concatenate(cols))),
                       shape=(n + 2, n + 2)).tocsr()
    distance, previous = dijkstra(graph, indices=n, return_predecessors=True)
    if not np.isfinite(distance[n + 1]):
        return np.array([], dtype=np.int64)
    chain, node = [], previous[n + 1]
    while node != n:
        chain.append(int(node))
        node = previous[node]
    return np.array(chain[::-1], dtype=np.int64)
