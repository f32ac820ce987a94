"""The shape annotations of the public API are checked at run time during the tests."""

import jax.numpy as jnp
import jaxtyping
import numpy as np
import pytest
from jaxtyping import Array, Float

import jaxbill as jb
import shape_checks
from conftest import UNRESOLVED_ANNOTATIONS


def test_every_annotated_public_function_resolves():
    assert UNRESOLVED_ANNOTATIONS == {}


@pytest.mark.parametrize("name", ["collide", "orbit", "tangent_map", "dynamical_frame", "lyapunov_spectrum", "run"])
def test_the_public_entry_points_are_checked(name):
    assert getattr(getattr(jb, name), shape_checks.CHECKED, False)


def test_a_wrong_shaped_argument_raises_jaxtypings_error():
    scene = jb.StickInCircle(R=2.0, ell=1.0, inertia=1.0)
    batch = np.zeros((2, 6))
    # the frame of StickInCircle does not depend on the state, so only the check sees the batch
    with pytest.raises(jaxtyping.TypeCheckError, match="argument 'state'"):
        jb.dynamical_frame(scene, batch)


def test_dimensions_named_twice_must_agree():
    def wrong(x: Float[Array, "B S"]) -> Float[Array, "B S"]:
        return x.T

    checked = shape_checks.check_shapes(wrong)
    assert checked(jnp.zeros((3, 3))).shape == (3, 3)
    with pytest.raises(jaxtyping.TypeCheckError, match="the result"):
        checked(jnp.zeros((2, 3)))


def test_an_orbits_fields_are_checked_against_its_annotations():
    scene = jb.StickInCircle(R=2.0, ell=1.0, inertia=1.0)
    state0 = np.array([[0.1, 0.0, 0.3, 0.5, 0.2, 0.1], [0.0, 0.2, -0.4, -0.3, 0.6, 0.2]])
    orbit = jb.orbit(scene, state0, 3)
    assert orbit.state.shape == (2, 3, 6)
