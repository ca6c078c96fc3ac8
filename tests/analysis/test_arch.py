"""The blocking arch (analysis/arch.py) on hand-built contact networks: an arch of three
disks over a hole between two lips, with a heap of disks resting on it."""
from types import SimpleNamespace

import numpy as np

from graindyn.analysis.arch import blocking_arch
from graindyn.core.engine import Contacts, WallContacts


def network(pairs, walls, positions):
    """A stand-in engine: Contacts of ``pairs`` (i, j, normal force) and WallContacts of
    ``walls`` (grain, wall, normal force) between disks at ``positions``; walls 0 and 1
    are the lips."""
    positions = np.asarray(positions, dtype=float)
    i = np.array([p[0] for p in pairs], dtype=np.int64)
    j = np.array([p[1] for p in pairs], dtype=np.int64)
    rel = positions[j] - positions[i]
    contacts = Contacts(i, j, 0.5 * rel, -0.5 * rel, np.array([p[2] for p in pairs], float),
                        np.zeros((len(pairs), 3)), -rel / np.linalg.norm(rel, axis=1)[:, None])
    g = np.array([w[0] for w in walls], dtype=np.int64)
    wall = WallContacts(g, np.array([w[1] for w in walls], dtype=np.int64),
                        np.tile([0.0, -1.0, 0.0], (len(walls), 1)),
                        np.array([w[2] for w in walls], float), np.zeros((len(walls), 3)),
                        np.tile([0.0, 1.0, 0.0], (len(walls), 1)))
    names = {"floor_left": 0, "floor_right": 1}
    return SimpleNamespace(
        state=SimpleNamespace(n=len(positions)),
        walls=SimpleNamespace(index=lambda w: names.get(w, w)),
        contacts=lambda: contacts, wall_contacts=lambda: wall)


# disks 0-2 span the hole (0 on the left lip, 2 on the right); 3-5 rest on them; 6 sits
# on the left lip alone; 7 touches 3 and 6 with no load
POSITIONS = [[1.0, 0.5, 0], [2.0, 1.2, 0], [3.0, 0.5, 0], [1.5, 1.9, 0], [2.5, 1.9, 0],
             [2.0, 2.6, 0], [0.0, 0.5, 0], [0.8, 1.6, 0]]
PAIRS = [(0, 1, 5.0), (1, 2, 5.0), (1, 3, 2.0), (1, 4, 2.0), (3, 4, 1.0), (3, 5, 1.0),
         (4, 5, 1.0), (0, 3, 1.5), (2, 4, 1.5), (0, 6, 0.5), (3, 7, 0.0), (6, 7, 0.0)]
WALLS = [(0, 0, 8.0), (2, 1, 8.0), (6, 0, 1.0)]


def test_the_arch_is_the_shortest_loaded_chain_between_the_lips():
    arch = blocking_arch(network(PAIRS, WALLS, POSITIONS), "floor_left", "floor_right")
    assert list(arch) == [0, 1, 2]


def test_a_contact_without_load_does_not_hold_the_arch():
    """Cut the loaded chain 0-1-2 at 1-2: the arch goes round through 4 (0-1-4-2), and
    with 1-4 unloaded too, through 3 and 4 (0-3-4-2); the unloaded 3-7-6 never counts."""
    cut = [p if p[:2] != (1, 2) else (1, 2, 0.0) for p in PAIRS]
    assert list(blocking_arch(network(cut, WALLS, POSITIONS), 0, 1)) == [0, 1, 4, 2]
    cut = [p if p[:2] not in ((1, 2), (1, 4)) else (*p[:2], 0.0) for p in PAIRS]
    assert list(blocking_arch(network(cut, WALLS, POSITIONS), 0, 1)) == [0, 3, 4, 2]


def test_no_chain_between_the_lips_means_no_arch():
    """The right lip carries nothing: the hole is open."""
    walls = [w for w in WALLS if w[1] != 1]
    assert blocking_arch(network(PAIRS, walls, POSITIONS), 0, 1).size == 0
