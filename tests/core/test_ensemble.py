"""graindyn.Ensemble on the CPU (members one after another) and the checks an ensemble
makes before it runs; the GPU ensemble, where members share kernels, is checked member
by member against the same systems alone in tests/gpu (under the CUDA simulator)."""
import numpy as np
import pytest

import graindyn as gd
from graindyn.engines.soft.simulation import OverlapError
from graindyn.engines.soft.gpu.layout import Layout


def bed(seed, model=("hertz", "tsuji", "mindlin"), deep=False):
    rng = np.random.default_rng(seed)
    g = (np.arange(2) + 0.5) * 2.1e-3
    pos = np.stack(np.meshgrid(g, g, g), -1).reshape(-1, 3)
    pos += rng.normal(scale=5e-5, size=pos.shape)
    if deep:
        pos[1] = pos[0] + [1.2e-3, 0.0, 0.0]
    state = gd.State.create(pos, rng.uniform(0.95e-3, 1.05e-3, len(pos)), 2650.0)
    state.velocities[:] = rng.normal(scale=0.3, size=pos.shape)
    return gd.Simulation(state, [gd.Material(youngs_modulus=1e7, restitution=0.8, friction_sliding=0.5)],
                         gd.ContactModel(*model),
                         walls=gd.box((0, 0, 0), (4.2e-3, 4.2e-3, 8e-3)), dt=2e-6,
                         check_interval=5)


def test_members_run_as_they_would_alone(one_thread):
    """Per-member steps and conditions; a member that fails is reported, not raised,
    and the others go on; every member ends where it ends alone."""
    speed = 2.0 * float(np.linalg.norm(bed(2).state.velocities, axis=1).max())
    until = [None, gd.MaxSpeedBelow(speed), None]
    alone = [bed(1), bed(2), bed(3, deep=True)]
    results = [alone[0].run(steps=30), alone[1].run(steps=20, until=until[1])]
    with pytest.raises(OverlapError):
        alone[2].run(steps=30)
    members = [bed(1), bed(2), bed(3, deep=True)]
    outcomes = gd.Ensemble(members).run(steps=[30, 20, 30], until=until)
    assert outcomes[:2] == results == ["done", "condition"]
    assert isinstance(outcomes[2], OverlapError)
    for a, b in zip(alone, members):
        x, y = a.snapshot(), b.snapshot()
        assert all(np.array_equal(x[k], y[k]) for k in x)
    assert [m.step for m in members] == [30, 5, 0]


def test_ensemble_inputs_are_checked():
    with pytest.raises(ValueError, match="at least one"):
        gd.Ensemble([])
    with pytest.raises(ValueError, match="one value per member"):
        gd.Ensemble([bed(1), bed(2)]).run(steps=[10, 10, 10])
    with pytest.raises(ValueError, match="one contact model"):
        Layout.check([bed(1), bed(2, model=("hertz", "tsuji", "coulomb"))])
