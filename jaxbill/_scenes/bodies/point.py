"""A point particle: one contact, at its centre; its spin (if any) is a free rotor."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike

from jaxbill._engine.validation import check_parameter, is_concrete, real_parameter
from jaxbill._scenes.bodies.base import Body, checked_mass_and_inertia, scalar_leaf


class PointBody(Body):
    """A point particle of mass ``M``: the classical billiard.

    Args:
        mass: ``M > 0`` (default 1).
        inertia: the moment of inertia of its free spin, ``>= 0`` (default 0): the
            wall exerts no torque on a point, so ``omega`` never changes and only
            counts in the energy.
    """

    mass: jax.Array
    inertia: jax.Array
    kind: str = eqx.field(static=True)

    @property
    def contact_names(self):
        return ("the point",)

    def __init__(self, mass: ArrayLike = 1.0, inertia: ArrayLike = 0.0):
        if is_concrete(mass) and is_concrete(inertia):
            mass, inertia, _ = checked_mass_and_inertia(mass, inertia, point=True)
        self.mass, self.inertia = scalar_leaf(mass), scalar_leaf(inertia)
        self.kind = "point"

    def check(self) -> None:
        checked_mass_and_inertia(self.mass, self.inertia, point=True)

    def parameters_are_valid(self):
        return (self.mass > 0) & jnp.isfinite(self.mass) & (self.inertia >= 0)

    @property
    def radius(self):
        return jnp.zeros_like(self.mass)

    def offsets(self, cos, sin):
        return None


def checked_length(name: str, value, meaning: str) -> np.ndarray:
    """A concrete length, > 0 and finite, or ValueError naming it."""
    value = real_parameter(name, value)
    check_parameter(name, value, np.isfinite(value) & (value > 0), f"> 0 and finite ({meaning})")
    return value
