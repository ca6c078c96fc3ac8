"""Bad input is refused before any work starts, with a message naming what is wrong."""
import numpy as np
import pytest

import graindyn as gd


def _state(dim=3):
    return gd.State.create([[0, 0, 1e-3], [0, 0, 3e-3]][:2] if dim == 3 else [[0, 1e-3],
                                                                            [0, 3e-3]],
                           [1e-3, 1e-3], 2650.0, dim=dim)


@pytest.mark.parametrize("kwargs, match", [
    (dict(density=-1.0), "density"),
    (dict(poisson_ratio=0.6), "poisson_ratio"),
    (dict(restitution=1.5), "restitution"),
    (dict(friction_sliding=-0.1), "friction_sliding"),
])
def test_bad_material(kwargs, match):
    with pytest.raises(ValueError, match=match):
        gd.Material(**kwargs)


@pytest.mark.parametrize("model, material, match", [
    (gd.ContactModel("hooke"), gd.Material(), "kn > 0"),
    (gd.ContactModel("hertz", "tsuji"), gd.Material(), "needs restitution"),
    (gd.ContactModel("hertz", "viscoelastic"), gd.Material(), "gamma_n"),
    (gd.ContactModel("hertz", "linear"), gd.Material(restitution=0.5), "goes with normal"),
    (gd.ContactModel("hooke", "none", "cundall_strack"), gd.Material(kn=1e3), "kt > 0"),
    (gd.ContactModel("hertz", "magic"), gd.Material(), "unknown damping law 'magic'"),
])
def test_bad_contact_model(model, material, match):
    with pytest.raises(ValueError, match=match):
        gd.Simulation(_state(), [material], model)


@pytest.mark.parametrize("kwargs, match", [
    (dict(gravity=(0, -9.81)), "3-vector"),
    (dict(dt=-1e-6), "time step"),
    (dict(skin=0.0), "skin"),
    (dict(walls=[gd.Plane((0, 0, 0), (0, 0, 1), material=3)]), "wall material"),
    (dict(walls=[gd.Plane((0, 0, 0), (0, 0, 0))]), "normal"),
    (dict(walls=[gd.Cylinder((0, 0, 0), (0, 0, 1), -1.0)]), "radius"),
    (dict(periodic=[gd.PeriodicBoundary(0, 0.0, 1e-3)]), "periodic length"),
    (dict(integrator="euler"), "unknown integrator"),
])
def test_bad_simulation_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        gd.Simulation(_state(), [gd.Material()], gd.ContactModel(), **kwargs)


def test_2d_gravity_must_stay_in_plane():
    with pytest.raises(ValueError, match="zero z component in 2D"):
        gd.Simulation(_state(2), [gd.Material()], gd.ContactModel(), gravity=(0, 0, -9.81))


def test_bad_state_and_radii():
    with pytest.raises(ValueError, match="radii must be positive"):
        gd.State.create([[0, 0, 0]], [0.0], 2650.0)
    with pytest.raises(ValueError, match="dim must be 2 or 3"):
        gd.State.create([[0, 0, 0]], [1e-3], 2650.0, dim=4)
    with pytest.raises(ValueError, match="unknown diameter distribution"):
        gd.sample_radii(5, "weibull", np.random.default_rng(0))
    with pytest.raises(ValueError, match="run needs steps= or time="):
        gd.Simulation(_state(), [gd.Material()], gd.ContactModel(),
                      gravity=(0, 0, 0)).run()


def test_state_owns_writable_copies_of_what_it_is_given():
    """A read-only view (np.broadcast_to of one radius) or the caller's own array become
    the State's own writable copies: the compiled loop is typed on writable arrays, and
    a second type would compile it again."""
    mine = np.array([1e-3, 2e-3])
    st = gd.State.create([[0, 0, 0], [0, 0, 1e-2]], mine, 2650.0, materials=np.zeros(2, int))
    one = gd.State.create([[0, 0, 0]], np.broadcast_to(1e-3, 1), 2650.0)
    assert one.radii.flags.writeable and st.radii.flags.writeable
    assert not np.shares_memory(st.radii, mine) and st.materials.dtype == np.int32
