"""The stick in an ellipse: a rigid stick bouncing elastically inside ``x^2/a^2 + y^2/b^2 <= 1``.

State layout (float64, shape ``(6,)``), as for ``StickInCircle``::

    [x, y, alpha, vx, vy, omega]

``(x, y)`` is the stick's centre (length units), ``alpha`` the angle of end P1
from the x axis (radians), ``(vx, vy)`` the centre's velocity and ``omega`` the
spin (radians per time unit). The ends are ``P_k = c + k ell u``,
``u = (cos alpha, sin alpha)``, ``k = +1`` for P1 (contact ``+1``) and ``-1``
for P2 (contact ``-1``); ``2`` is both ends at once, ``0`` none.

The table and the gaps. Semi-axis ``a`` lies along x and ``b`` along y; either
may be the larger (the physics is the same turned by a quarter turn). Each
end's gap is ``g_k = a b - P_k^T D P_k``, ``D = diag(b/a, a/b)``: a positive
multiple of ``1 - x^2/a^2 - y^2/b^2``, scaled so that for ``a = b = R`` it is
the circle's ``R^2 - |P_k|^2``. The bounds the first-root search needs (the
range of ``g_k''`` along a flight and a quiet region of the centre) are
derived in ``jaxbill._scenes.tables.ellipse``.

The impulse. In the configuration ``q = (x, y, alpha)`` with the mass matrix
``diag(M, M, I)``, ``grad_q g_k = -2 (N, s_k)`` with the outward normal
``N = D P_k`` and the lever ``s_k = k ell (u x N)``; the mass-metric reflection
about it is, with ``v_n = v . N + omega s_k``,
``w = 2 v_n / (|N|^2 + (M/I) s_k^2)``: ``v' = v - w N``,
``omega' = omega - w (M/I) s_k`` (``StickInCircle``'s law with ``N = P``).

Valid parameters and states. ``a, b > 0`` finite; ``0 <= ell < max(a, b)``:
the longest chord of the ellipse is its major axis, ``2 max(a, b)``, so a
longer stick fits nowhere. For ``min(a, b) <= ell`` the stick fits only in
orientations near the major axis and only near the centre of the table; a
valid state is then what it is for every stick: both ends strictly inside (a
gap ``>= -1e-12 ab`` counts as on the wall), or an end on the wall moving
inwards, as just after a collision. The ellipse is convex, so both ends inside
puts the whole stick inside; the orientations that fit follow from the state,
and the dynamics never leaves them (``check_state_values`` and ``is_valid``
enforce it through the gaps).

Invariants. The energy only, in general: the wall's normal does not pass
through the origin, so ``angular_momentum`` (about the centre of the table)
changes at every collision unless ``a = b``. For a point particle (``ell = 0``)
the product of the centre's angular momenta about the two foci,
``focal_momentum_product``, is conserved (the elliptic billiard is integrable).
"""

from __future__ import annotations

import math
from typing import ClassVar, cast

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike

from jaxbill._engine.step import components, cos_sin, searched_contact_time, stacked
from jaxbill._engine.validation import (
    broadcast_parameters,
    check_parameter,
    is_concrete,
    real_parameter,
    require_x64,
)
from jaxbill._scenes import impulse
from jaxbill._scenes.bodies.dumbbell import Dumbbell
from jaxbill._scenes.bodies.point import PointBody
from jaxbill._scenes.body_in_table import BodyInTable
from jaxbill._scenes.ellipse.sections import (
    ELLIPSE_CHART,
    SECTION_AXIS_LABELS,
    SECTIONS,
    ellipse_section,
    ellipse_section_state,
)
from jaxbill._scenes.protocols import NO_CONTACT, SEVERAL_CONTACTS, SectionChart, StickColumn, chosen_section
from jaxbill._scenes.shell_sampling import table_shell_candidates
from jaxbill._scenes.tables.ellipse import Ellipse

KINDS = ("rotor", "static", "point")


def _checked_parameters(a, b, ell, mass, inertia):
    """Validate concrete parameters; return them broadcast to one shape, and the scene kind."""
    named = (("a", a), ("b", b), ("ell", ell), ("mass", mass))
    a, b, ell, mass = (real_parameter(name, v) for name, v in named)
    if inertia is not None:
        inertia = real_parameter("inertia", inertia)
    broadcast_parameters(a=a, b=b, ell=ell, mass=mass, inertia=inertia)
    for name, v in (("a", a), ("b", b), ("ell", ell), ("mass", mass)):
        check_parameter(name, v, np.isfinite(v), "finite")
    check_parameter("a", a, a > 0, "> 0 (the semi-axis along x)")
    check_parameter("b", b, b > 0, "> 0 (the semi-axis along y)")
    check_parameter("ell", ell, ell >= 0, ">= 0")
    a_, b_, ell_ = np.broadcast_arrays(a, b, ell)
    check_parameter(
        "ell",
        ell_,
        ell_ < np.maximum(a_, b_),
        "< max(a, b) (the stick must fit along the major axis, the longest chord)",
    )
    check_parameter("mass", mass, mass > 0, "> 0")
    point = bool(np.all(ell == 0))
    if not point and np.any(ell == 0):
        raise ValueError("ell must be all zero or all positive within one batch of scenes")
    if inertia is None:
        inertia = mass * ell**2
    else:
        check_parameter("inertia", inertia, ~np.isnan(inertia), "a number or inf, not NaN")
        check_parameter("inertia", inertia, inertia > 0, "> 0 (or inf for a stick that never turns)")
    static = (not point) and bool(np.all(np.isinf(inertia)))
    if not point and not static and np.any(np.isinf(inertia)):
        raise ValueError("inertia must be all finite or all inf within one batch of scenes")
    kind = "point" if point else ("static" if static else "rotor")
    return (*np.broadcast_arrays(a, b, ell, mass, inertia), kind)


class StickInEllipse(BodyInTable):
    """A stick of half-length ``ell`` bouncing elastically inside the ellipse ``x^2/a^2 + y^2/b^2 <= 1``.

    Args:
        a: semi-axis along x, ``a > 0`` (length).
        b: semi-axis along y, ``b > 0``; either of ``a``, ``b`` may be the larger.
        ell: half-length of the stick, ``0 <= ell < max(a, b)``. For
            ``ell >= min(a, b)`` the stick fits only in some orientations (see
            the module docstring). ``ell = 0`` is the elliptic billiard of a
            point (the spin decouples).
        mass: total mass ``M > 0`` (default 1).
        inertia: moment of inertia about the centre, ``I > 0``. ``None`` means
            ``mass * ell**2``; ``float('inf')`` is a stick that never turns
            (``omega`` must then be 0).

    Parameters may be arrays of one common shape ``(B,)`` (scalars broadcast),
    a batch of scenes for ``jax.vmap(..., in_axes=(0, ...))``.

    The leaves ``a, b, ell, mass, inertia`` are differentiable. ``kind`` is
    static and chooses the compiled code: ``"static"`` (infinite inertia) and
    ``"point"`` (``ell = 0``) have closed-form collision times (each gap is a
    quadratic in ``t``); ``"rotor"`` uses the safe-step root search.
    """

    state_size: ClassVar[int] = 6
    state_layout: ClassVar[str] = "[x, y, alpha, vx, vy, omega]"
    gap_names: ClassVar[tuple[str, ...]] = ("end P1", "end P2")
    wall_name: ClassVar[str] = "the ellipse"
    never_turning: ClassVar[str] = "a stick that never turns"

    def __init__(
        self,
        a: ArrayLike,
        b: ArrayLike,
        ell: ArrayLike,
        mass: ArrayLike = 1.0,
        inertia: ArrayLike | None = None,
        *,
        kind: str | None = None,
    ):
        require_x64()
        leaves = [a, b, ell, mass] + ([] if inertia is None else [inertia])
        if all(is_concrete(v) for v in leaves):
            a, b, ell, mass, inertia, guessed = _checked_parameters(a, b, ell, mass, inertia)
        else:
            # Traced parameters cannot be checked here; invalid ones poison
            # the results with NaN instead (``is_valid``).
            if inertia is None:
                inertia = mass * ell**2
            static_literal = isinstance(inertia, float) and math.isinf(inertia)
            guessed = "static" if static_literal else "rotor"
        if kind is not None and kind not in KINDS:
            raise ValueError(f"kind must be one of {KINDS}; got {kind!r}")
        kind = guessed if kind is None else kind
        if kind == "point":
            body = PointBody(jnp.asarray(mass, jnp.float64), jnp.asarray(inertia, jnp.float64))
        else:
            body = Dumbbell(jnp.asarray(ell, jnp.float64), None, mass, inertia, kind=kind)
        super().__init__(body, Ellipse(a, b))

    def check(self) -> None:
        """Raise ValueError if the parameters are invalid or do not fit ``kind``."""
        default = self.kind == "point" and is_concrete(self.inertia) and np.all(np.asarray(self.inertia) == 0)
        *_, kind = _checked_parameters(self.a, self.b, self.ell, self.mass, None if default else self.inertia)
        if kind != self.kind:
            raise ValueError(
                f"the parameters describe a {kind!r} scene but this scene was compiled as {self.kind!r} "
                "(inertia = inf is the static stick, ell = 0 the point): build a new StickInEllipse"
            )

    # -- the parameters -----------------------------------------------------------------

    @property
    def a(self) -> jax.Array:
        """The semi-axis along x."""
        return cast(Ellipse, self.table).a

    @property
    def b(self) -> jax.Array:
        """The semi-axis along y."""
        return cast(Ellipse, self.table).b

    @property
    def ell(self) -> jax.Array:
        """The stick's half-length (0 for the point)."""
        return jnp.zeros_like(cast(Ellipse, self.table).a) if self.kind == "point" else cast(Dumbbell, self.body).l1

    @property
    def gap_codes(self) -> tuple[int, ...]:
        """End P1 touching is contact ``+1``, end P2 ``-1``."""
        return (1,) if self.kind == "point" else (1, -1)

    @property
    def contact_codes(self) -> tuple[int, ...]:
        return (NO_CONTACT, 1) if self.kind == "point" else (-1, NO_CONTACT, 1, SEVERAL_CONTACTS)

    @property
    def inverse_inertia(self) -> jax.Array:
        """``1/I``; zero where the spin is never kicked (static stick, point)."""
        if self.kind == "rotor":
            return 1.0 / self.inertia
        return jnp.zeros_like(self.inertia)

    # -- the stick's own geometry and engine steps, on arrays ------------------------------

    def direction(self, state: jax.Array) -> jax.Array:
        """The stick's unit vector ``u = (cos alpha, sin alpha)``, shape ``(..., 2)`` (``(1, 0)`` for a point)."""
        alpha = jnp.asarray(state)[..., 2]
        if self.kind == "point":
            return jnp.stack([jnp.ones_like(alpha), jnp.zeros_like(alpha)], axis=-1)
        return jnp.stack(cos_sin(alpha), axis=-1)

    def end_points(self, state: jax.Array) -> jax.Array:
        """Ends ``[P1, P2]``, shape ``(..., 2, 2)``."""
        c = jnp.asarray(state)[..., 0:2]
        offset = self.ell[..., None] * self.direction(state)
        return jnp.stack([c + offset, c - offset], axis=-2)

    def kick(self, state: tuple, end, u: tuple) -> tuple:
        """Elastic frictionless impulse at end ``end`` (+1 or -1) on the wall, the stick along ``u``: the
        mass-metric reflection about ``N = D P`` (the table's ``-grad g / 2``), components in and out."""
        x, y = state[0], state[1]
        rx, ry = end * self.ell * u[0], end * self.ell * u[1]
        normal = self.table.pieces[0].impulse_normal(x + rx, y + ry)
        tx, ty = self.body.turn_vector(rx, ry)
        return impulse.reflect(state, normal[0] * tx + normal[1] * ty, normal, self.body.mass_ratio)

    def root_search_setup(self, state: tuple):
        """The first-root search's bounds for the flight from ``state``: ``(lower_curv, upper_curv, quiet_in,
        quiet_out, time_scale)`` (``jaxbill._engine.first_root.RootBounds``; derivations in
        ``jaxbill._scenes.tables.ellipse``)."""
        return tuple(self.root_search(state)[1][:5])

    def contact_gaps(self, state: jax.Array, t: jax.Array):
        """``gaps_along_flight`` of a state array ``(6,)`` as arrays: ``(gap, slope)``, each ``(2,)``."""
        gaps, slopes = self.gaps_along_flight(components(state), t)[:2]
        return jnp.stack(gaps), jnp.stack(slopes)

    def resolve_contact(self, state: jax.Array, index: jax.Array):
        """The impulse(s) at a contact of end ``index`` (0: P1, 1: P2) of a state ``(6,)`` at the contact:
        ``(new_state, contact)``."""
        parts = components(state)
        new, contact = self.resolve(parts, index, self._offsets(parts[2]))
        return stacked(new), contact

    def next_contact(self, state: jax.Array, static_direction: jax.Array | None = None):
        """``(t, index, ok)``: time to the next contact (``inf`` if none), which end (0: P1, 1: P2), and
        ``ok = False`` if the root search hit its step bound. Differentiable (implicitly, for the search)."""
        parts = components(state)
        if self.kind == "rotor":
            return searched_contact_time(self, parts)
        constants = self.orbit_constants(parts)
        if static_direction is not None and self.kind == "static":
            constants = self.body.offsets(*components(static_direction))
        t, index = self.closed_form_contact(parts, constants)
        return t, index, jnp.array(True)

    @property
    def foci(self) -> jax.Array:
        """The table's foci ``(2, 2)``: ``(+-sqrt(a^2 - b^2), 0)`` for ``a >= b``, else on the y axis."""
        half = jnp.sqrt(jnp.abs(self.a**2 - self.b**2))
        zero = jnp.zeros_like(half)
        focus = jnp.where(self.a >= self.b, jnp.stack([half, zero]), jnp.stack([zero, half]))
        return jnp.stack([focus, -focus])

    def focal_momentum_product(self, state: jax.Array) -> jax.Array:
        """``L1 L2``, the centre's angular momenta ``M (c - F_i) x v`` about the two foci, shape ``(...)``.

        Conserved for a point (``ell = 0``), where it is the elliptic billiard's
        second integral; the spin is left out (it decouples there). For ``a = b``
        it is the square of the orbital angular momentum.
        """
        c, v = state[..., 0:2], state[..., 3:5]
        cross = c[..., 0] * v[..., 1] - c[..., 1] * v[..., 0]
        foci = self.foci
        moments = [self.mass * (cross - (f[0] * v[..., 1] - f[1] * v[..., 0])) for f in foci]
        return moments[0] * moments[1]

    # -- what the analyses ask (jaxbill._scenes.protocols's capability protocols) ---------------------

    sections: ClassVar[tuple[str, ...]] = SECTIONS
    section_axis_labels: ClassVar[dict[str, tuple[str, str]]] = SECTION_AXIS_LABELS
    # Area-preserving for the point (ell = 0); for a stick a projection (jaxbill._scenes.ellipse.sections).
    area_preserving_section: ClassVar[str] = "birkhoff"

    def section(self, states: jax.Array, contacts: jax.Array | None = None, name: str | None = None) -> jax.Array:
        """Section points ``(..., 2)`` of states ``(..., 6)`` at collisions (``HasSection``).

        ``"birkhoff"`` (default): ``[s, p]``, the arc length of the touching
        end's contact from ``(a, 0)`` and its tangential momentum
        ``sqrt(M) v_t / sqrt(2E)``; area-preserving for a point (``ell = 0``).
        ``"angle"``: ``[t, p]`` with the parameter angle ``t`` of the contact,
        ``P = (a cos t, b sin t)``. ``contacts`` (``Orbit.contact``) name the
        touching end; without them, the end with the smaller gap.
        See ``jaxbill._scenes.ellipse.sections``.
        """
        return ellipse_section(self, states, contacts, chosen_section(self, name))

    def section_state(self, point: ArrayLike, energy=0.5, arm_angle=0.0, spin=0.0) -> jax.Array:
        """The state ``(..., 6)`` just after end P1 hits the wall at the Birkhoff section's ``point = (s, p)``,
        shape ``(..., 2)``: energy ``E``, the stick at ``arm_angle`` (radians) from the outward normal, spin
        ``omega``; NaN where none exists (``jaxbill._scenes.ellipse.sections.ellipse_section_state``)."""
        xy = jnp.asarray(point, dtype=jnp.float64)
        return ellipse_section_state(self, xy[..., 0], xy[..., 1], energy, arm_angle, spin)

    @property
    def section_chart(self) -> SectionChart:
        """The explorer's chart of the Birkhoff section (P1 on the wall, stick along the normal, no spin)."""
        return ELLIPSE_CHART

    def checker_flight(self) -> StickColumn:
        """The column ``g_k(x, y, z / sqrt(I/M)) >= 0`` in ``(x, y, z = sqrt(I/M) alpha)`` (``HasCheckerFlight``).

        The gaps' Hessian in the contact point is ``-2 D``, ``|D| = max(a, b) / min(a, b)``; the centre
        of a stick with both ends inside the convex table is inside it, ``|c| <= max(a, b)``.
        """
        turning = self.kind == "rotor"
        scale = jnp.sqrt(self.inertia / self.mass) if turning else jnp.ones_like(self.a)
        major, minor = jnp.maximum(self.a, self.b), jnp.minimum(self.a, self.b)
        return StickColumn(
            scale=scale,
            length=major,
            reach=major,
            hessian_bound=major / minor,
            frozen=self.kind == "static",
            single_sheet=self.kind == "point",
        )

    def sample_states(self, rng, count: int, energy: float, angular_momentum=None, margin: float = 1e-9):
        """``count`` tries at Liouville-distributed states of energy ``E`` (``SamplesStates``): the
        ``(states (k, 6), weights (k,))`` with both ends inside by ``margin ab`` (``jb.sample_energy_shell``
        loops over it). No angular momentum is conserved: ``angular_momentum`` must be None."""
        return table_shell_candidates(self, rng, count, energy, angular_momentum, margin)
