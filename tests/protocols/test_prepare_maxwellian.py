"""Maxwellian initial velocities: exact granular temperature, no drift, normal components."""
import numpy as np
import pytest
from scipy import stats

from graindyn.protocols.prepare import maxwellian_velocities


@pytest.mark.parametrize("dim", [2, 3])
def test_maxwellian_velocities(dim):
    rng = np.random.default_rng(2024)
    n, temperature = 20000, 3e-9
    masses = rng.uniform(0.5e-6, 2e-6, n)
    v = maxwellian_velocities(masses, temperature, rng, dim)
    assert v.shape == (n, 3)
    momentum = masses @ v
    assert np.all(np.abs(momentum) <= 1e-12 * np.sum(masses * np.linalg.norm(v, axis=1)))
    # T = sum m |v|^2 / (dim N): the kinetic energy is dim N T / 2
    kinetic = 0.5 * np.sum(masses[:, None] * v**2)
    assert kinetic == pytest.approx(0.5 * dim * n * temperature, rel=1e-12)
    # each component of grain i is normal with variance T / m_i
    for axis in range(dim):
        assert stats.kstest(v[:, axis] * np.sqrt(masses / temperature), "norm").pvalue > 1e-3
    if dim == 2:
        assert np.all(v[:, 2] == 0)


def test_zero_temperature_is_at_rest(rng):
    assert np.all(maxwellian_velocities(np.ones(5), 0.0, rng) == 0)


@pytest.mark.parametrize("masses, temperature, match", [
    ([1.0, 2.0], -1e-9, "temperature = -1e-09"),
    ([1.0, 2.0], np.nan, "temperature = nan"),
    ([], 1e-9, "masses"),
    ([1.0, 0.0], 1e-9, "masses"),
    ([1.0], 1e-9, "masses: one grain"),
])
def test_bad_arguments_are_refused(rng, masses, temperature, match):
    with pytest.raises(ValueError, match=match):
        maxwellian_velocities(masses, temperature, rng)
