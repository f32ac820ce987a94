"""A dumbbell (a stick): two contact points on a line through the centre of mass.

The points are ``b_1 = (+l1, 0)`` and ``b_2 = (-l2, 0)`` in the body's frame,
so ``P1 = c + l1 u`` and ``P2 = c - l2 u``, ``u = (cos alpha, sin alpha)``:
point masses ``m1 = M l2 / (l1 + l2)`` and ``m2 = M l1 / (l1 + l2)`` at them
put the centre of mass at ``c``, with the moment of inertia
``m1 l1^2 + m2 l2^2 = M l1 l2`` (``M ell^2`` for the symmetric stick). With the
weights ``m1 / M`` and ``m2 / M`` the contacts' barycentre is the centre:
``inner_radius2 = l1 l2``.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike

from jaxbill._engine.validation import broadcast_parameters, is_concrete
from jaxbill._scenes.bodies.base import Body, checked_mass_and_inertia, scalar_leaf
from jaxbill._scenes.bodies.point import checked_length


class Dumbbell(Body):
    """Two point contacts at distances ``l1`` and ``l2`` from the centre of mass, on opposite sides.

    Args:
        l1: distance of end P1 from the centre of mass, ``> 0`` (length).
        l2: distance of end P2, ``> 0``; default ``l1`` (a symmetric stick).
        mass: total mass ``M > 0`` (default 1).
        inertia: moment of inertia about the centre of mass, ``> 0``;
            ``None`` means ``M l1 l2`` (the masses at the ends);
            ``float('inf')``: a dumbbell that never turns (``omega`` must be 0).

    Unequal ``l1, l2`` with the default inertia is a dumbbell of unequal masses
    (``Dumbbell.from_masses``).
    """

    l1: jax.Array
    # ``None`` for a symmetric stick: one leaf, ``ell``, sets both arms.
    second_arm: jax.Array | None
    mass: jax.Array
    inertia: jax.Array
    kind: str = eqx.field(static=True)

    @property
    def contact_names(self):
        return ("end P1", "end P2")

    def __init__(
        self,
        l1: ArrayLike,
        l2: ArrayLike | None = None,
        mass: ArrayLike = 1.0,
        inertia: ArrayLike | None = None,
        *,
        kind: str | None = None,
    ):
        if inertia is None:
            inertia = mass * l1 * (l1 if l2 is None else l2)
        if all(is_concrete(v) for v in (l1, l2, mass, inertia)):
            l1 = checked_length("l1", l1, "the distance of end P1 from the centre of mass")
            if l2 is not None:
                l2 = checked_length("l2", l2, "the distance of end P2 from the centre of mass")
            broadcast_parameters(l1=l1, l2=l2, mass=mass, inertia=inertia)
            mass, inertia, guessed = checked_mass_and_inertia(mass, inertia)
        else:
            # Traced parameters cannot be checked here; invalid ones poison the results with NaN.
            guessed = "static" if isinstance(inertia, float) and math.isinf(inertia) else "rotor"
        self.l1, self.mass, self.inertia = (scalar_leaf(v) for v in (l1, mass, inertia))
        self.second_arm = None if l2 is None else scalar_leaf(l2)
        if kind is not None and kind not in ("static", "rotor"):
            raise ValueError(f"kind must be 'static' or 'rotor'; got {kind!r}")
        self.kind = guessed if kind is None else kind

    @property
    def l2(self) -> jax.Array:
        """The distance of end P2 from the centre of mass (``l1`` for a symmetric stick)."""
        return self.l1 if self.second_arm is None else self.second_arm

    @classmethod
    def from_masses(cls, m1, m2, length, inertia=None) -> Dumbbell:
        """Point masses ``m1`` (end P1) and ``m2`` (end P2), ``length`` apart: ``l1 = m2 length / (m1 + m2)``."""
        total = np.asarray(m1, dtype=np.float64) + np.asarray(m2, dtype=np.float64)
        return cls(m2 * np.asarray(length) / total, m1 * np.asarray(length) / total, total, inertia)

    def check(self) -> None:
        checked_length("l1", self.l1, "the distance of end P1 from the centre of mass")
        checked_length("l2", self.l2, "the distance of end P2 from the centre of mass")
        *_, kind = checked_mass_and_inertia(self.mass, self.inertia)
        if kind != self.kind:
            raise ValueError(f"inertia = {self.inertia} makes a {kind!r} dumbbell, not {self.kind!r}: build a new one")

    def parameters_are_valid(self):
        # A zero arm is a valid limit (the stick shrunk to a spinning point) inside jit, as the circle's ell >= 0.
        ok = (self.l1 >= 0) & (self.l2 >= 0) & jnp.isfinite(self.l1) & jnp.isfinite(self.l2)
        ok &= (self.mass > 0) & jnp.isfinite(self.mass)
        if self.kind == "rotor":
            ok &= (self.inertia > 0) & jnp.isfinite(self.inertia)
        return ok

    @property
    def radius(self):
        return self.l1 if self.second_arm is None else jnp.maximum(self.l1, self.l2)

    @property
    def inner_radius2(self):
        return self.l1 * self.l2

    @property
    def diameter(self):
        return self.l1 + self.l2

    @property
    def turn_symmetry(self) -> int:
        """2 for a symmetric stick (its ends swapped), else 1."""
        return 2 if self.second_arm is None else 1

    def offsets(self, cos, sin):
        # -(l2 cos) rather than (-l2) cos: P2 = c - l2 u to the bit, as the stick's own formula.
        return (self.l1 * cos, self.l1 * sin), (-(self.l2 * cos), -(self.l2 * sin))
