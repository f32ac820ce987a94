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
derived in ``jaxbill._scenes.smooth_table``.

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
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike

from jaxbill._analysis.chaos import table_shell_candidates
from jaxbill._check.checker import ColumnFlight
from jaxbill._engine.first_root import RootBounds, first_smallest
from jaxbill._engine.step import components, cos_sin, searched_contact_time, stacked
from jaxbill._engine.validation import (
    broadcast_parameters,
    check_parameter,
    is_concrete,
    motion_is_representable,
    on_wall_not_inwards,
    real_parameter,
    require_x64,
)
from jaxbill._scenes import two_ended_stick as stick
from jaxbill._scenes.ellipse.sections import (
    ELLIPSE_CHART,
    SECTION_AXIS_LABELS,
    SECTIONS,
    ellipse_section,
    ellipse_section_state,
)
from jaxbill._scenes.protocols import WALL_TOLERANCE, SectionChart, chosen_section, component
from jaxbill._scenes.smooth_table import EllipseTable

# Orbits per vectorised lane of a batch on a CPU (see the circle's). A turning stick's
# orbits run one after another: in lanes of 16 they ran 1.05x faster, but their last
# bits then depended on the number of devices (a two-device mesh differed from one and
# from the orbit alone; not explained), and one by one each is bitwise the orbit alone.
_BATCH_CHUNK = {"rotor": 1, "static": 256, "point": 256}

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


class StickInEllipse(eqx.Module):
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

    What the engine asks of it, for one orbit's values: ``root_search_setup``
    (the search's bounds), ``contact_gaps`` (the gaps along a flight) and
    ``resolve_contact`` (the impulses at a contact); ``jaxbill._engine.step`` composes
    them (through ``root_search``, ``gaps_along_flight``, ``collide_at``) with
    the safe-step search, or with ``closed_form_contact`` for the static
    stick and the point.
    """

    a: jax.Array
    b: jax.Array
    ell: jax.Array
    mass: jax.Array
    inertia: jax.Array
    kind: str = eqx.field(static=True)

    state_size: ClassVar[int] = 6
    state_layout: ClassVar[str] = "[x, y, alpha, vx, vy, omega]"
    gap_names: ClassVar[tuple[str, ...]] = ("end P1", "end P2")
    wall_name: ClassVar[str] = "the ellipse"

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
        self.a, self.b, self.ell, self.mass, self.inertia = (
            jnp.asarray(v, dtype=jnp.float64) for v in (a, b, ell, mass, inertia)
        )
        if kind is not None and kind not in KINDS:
            raise ValueError(f"kind must be one of {KINDS}; got {kind!r}")
        self.kind = guessed if kind is None else kind

    def check(self) -> None:
        """Raise ValueError if the parameters are invalid or do not fit ``kind``."""
        default = self.kind == "point" and is_concrete(self.inertia) and np.all(np.asarray(self.inertia) == 0)
        *_, kind = _checked_parameters(self.a, self.b, self.ell, self.mass, None if default else self.inertia)
        if kind != self.kind:
            raise ValueError(
                f"the parameters describe a {kind!r} scene but this scene was compiled as {self.kind!r} "
                "(inertia = inf is the static stick, ell = 0 the point): build a new StickInEllipse"
            )

    @property
    def table(self) -> EllipseTable:
        return EllipseTable(self.a, self.b)

    # -- what the collision engine asks of a scene (see jaxbill._scenes.protocols) -------

    @property
    def batch_chunk(self) -> int:
        return _BATCH_CHUNK[self.kind]

    @property
    def gap_scale(self) -> jax.Array:
        return self.a * self.b

    @property
    def contact_codes(self) -> tuple[int, ...]:
        return stick.contact_codes(self.kind == "point")

    def check_state_values(self, state: np.ndarray) -> None:
        a = np.asarray(self.a)
        if a.ndim and state.ndim == 2 and a.shape[0] != state.shape[0]:
            raise ValueError(
                f"a batch of {a.shape[0]} scenes needs a batch of {a.shape[0]} states; got {state.shape[0]}"
            )
        if self.kind == "static" and np.any(state[..., 5] != 0):
            raise ValueError(
                "omega must be 0 for a stick that never turns (inertia = inf): an infinitely heavy stick cannot spin"
            )

    def is_valid(self, state: jax.Array) -> jax.Array:
        params_ok = (
            (self.a > 0)
            & (self.b > 0)
            & jnp.isfinite(self.a)
            & jnp.isfinite(self.b)
            & (self.ell >= 0)
            & (self.ell < jnp.maximum(self.a, self.b))
            & (self.mass > 0)
            & jnp.isfinite(self.mass)
        )
        if self.kind == "rotor":
            params_ok &= (self.inertia > 0) & jnp.isfinite(self.inertia)
        elif self.kind == "point":
            params_ok &= self.inertia >= 0
        state_ok = jnp.all(jnp.isfinite(state)) & self.motion_is_representable(state)
        gaps = self.gaps(state)
        inside = jnp.all(gaps >= -WALL_TOLERANCE * self.gap_scale)
        inside &= ~on_wall_not_inwards(gaps, self.approach_speeds(state))
        ok = params_ok & state_ok & inside
        if self.kind == "static":
            ok &= state[5] == 0.0
        return ok

    def motion_is_representable(self, state) -> jax.Array:
        """Traceable: ``|v|^2``, ``omega^2`` and the energy are ordinary float64 numbers."""
        size = jnp.maximum(self.a, self.b)
        return motion_is_representable(state[..., 3:5], state[..., 5] ** 2, self.energy(state), size)

    def orbit_constants(self, state0: tuple):
        """A stick that never turns keeps its direction ``(ux, uy)`` for a whole orbit (``state0``: components)."""
        return stick.direction(self.kind == "point", state0[2]) if self.kind == "static" else None

    # -- the engine's questions (jaxbill._engine.step) ----------------------------------
    # States are components (x, y, alpha, vx, vy, omega): scalars, or arrays of
    # one shape (a block of orbits inside a kernel), or a (6,) array; results
    # are tuples. jaxbill._engine.step differentiates the searched contact time
    # implicitly.

    @property
    def searches_for_roots(self) -> bool:
        """Static: a turning stick's gaps are transcendental in time; the others' are quadratics."""
        return self.kind == "rotor"

    def root_search(self, state: tuple):
        """``(profile, RootBounds)`` of the flight from ``state``: the profile is the state itself."""
        return state, RootBounds(*self.root_search_setup(state))

    def gaps_along_flight(self, state: tuple, t: jax.Array):
        """Both ends' gaps ``ab - P_k^T D P_k`` (area) and their time derivatives after a flight of ``t`` (2-tuples)."""
        x, y, alpha, vx, vy, omega = state
        cu, su = cos_sin(alpha + omega * t)
        table = self.table
        gaps, slopes = [], []
        for sign in (1.0, -1.0):
            arm = sign * self.ell
            px, py = x + vx * t + arm * cu, y + vy * t + arm * su
            ex, ey = vx - arm * omega * su, vy + arm * omega * cu
            nx, ny = table.normal_at(px, py)
            gaps.append(table.gap_at(px, py))
            slopes.append(-2.0 * (nx * ex + ny * ey))
        return tuple(gaps), tuple(slopes)

    def closed_form_contact(self, state: tuple, static_direction):
        """``(t, index)`` for the static stick and the point: each end (the point) moves on a line."""
        x, y, _, vx, vy, _ = state
        table = self.table
        if self.kind == "point":
            t = table.exit_time(x, y, vx, vy)
            return t, jnp.zeros(jnp.shape(t), jnp.int32)
        ux, uy = static_direction
        t_p1 = table.exit_time(x + self.ell * ux, y + self.ell * uy, vx, vy)
        t_p2 = table.exit_time(x - self.ell * ux, y - self.ell * uy, vx, vy)
        return jnp.minimum(t_p1, t_p2), first_smallest((t_p1, t_p2))

    def collide_at(self, state: tuple, t: jax.Array, index: jax.Array, static_direction):
        """The flight to ``t`` and the impulse(s) of end ``index`` (0: P1, 1: P2): ``(state, contact)``."""
        moved = stick.flight(self.kind != "static", state, t)
        u = static_direction if self.kind == "static" else stick.direction(self.kind == "point", moved[2])
        return self._resolve(moved, index, u)

    def root_search_setup(self, state: tuple):
        """The first-root search's bounds for the flight from ``state``.

        Returns ``(lower_curv, upper_curv, quiet_in, quiet_out, time_scale)``,
        scalars: ``-lower_curv <= g_k''(t) <= upper_curv`` for both ends and
        every ``t`` up to the first contact; ``(quiet_in, quiet_out)`` a time
        interval in which no end can touch (the centre inside the quiet
        ellipse; empty when ``ell >= min(a, b)``); ``time_scale`` a flight time
        to which the root is resolved. Valid for every kind (for ``static`` and
        ``point`` the curvature bounds are exact: each gap is a quadratic).
        Derivations: ``jaxbill._scenes.smooth_table``.
        """
        table = self.table
        x, y, _, vx, vy, omega = state
        if self.kind == "static":
            omega = jnp.zeros_like(omega)  # it never turns (and I = inf gives no spin term)
        p, q = table.metric
        centre_reach = jnp.maximum(table.reach(self.ell), jnp.sqrt((p * x) ** 2 + (q * y) ** 2))
        lower_curv, upper_curv = table.curvature_bounds(vx, vy, omega, self.ell, centre_reach)
        quiet_in, quiet_out = table.quiet_interval(x, y, vx, vy, self.ell)
        size = jnp.sqrt(table.gap_scale)
        time_scale = 1.0 / (jnp.sqrt(vx * vx + vy * vy) / size + jnp.abs(omega))
        return lower_curv, upper_curv, quiet_in, quiet_out, time_scale

    def contact_gaps(self, state: jax.Array, t: jax.Array):
        """``gaps_along_flight`` of a state array ``(6,)`` as arrays: ``(gap, slope)``, each ``(2,)``."""
        gaps, slopes = self.gaps_along_flight(components(state), t)
        return jnp.stack(gaps), jnp.stack(slopes)

    def resolve_contact(self, state: jax.Array, index: jax.Array):
        """The impulse(s) at a contact of end ``index`` (0: P1, 1: P2) of a state ``(6,)`` at the contact.

        Returns ``(new_state, contact)``. If the other end is on the wall too
        (to ``64`` ulps of ``ab``) and approaching, both are kicked, the faster
        one first and the other only if it still approaches, and the contact is 2.
        """
        parts = components(state)
        new, contact = self._resolve(parts, index, stick.direction(self.kind == "point", parts[2]))
        return stacked(new), contact

    def _resolve(self, state: tuple, index, u: tuple):
        if self.kind == "point":
            return self.kick(state, 0.0, u), jnp.ones(jnp.shape(index), jnp.int32)
        return stick.resolve_two_ends(
            self.kick, self._end_gap_and_closing, self._end_approach_speeds, state, index, u, self.gap_scale
        )

    def _end_gaps(self, state: tuple, u: tuple) -> tuple:
        return tuple(self._end_gap_and_closing(state, u, sign)[0] for sign in stick.END_SIGNS)

    def _end_gap_and_closing(self, state: tuple, u: tuple, sign) -> tuple:
        """The gap of the end ``c + sign ell u`` and its velocity along the wall's unnormalised normal there."""
        table = EllipseTable(self.a, self.b)
        px, py, ex, ey = stick.end_motion(state, u, sign * self.ell)
        nx, ny = table.normal_at(px, py)
        return table.gap_at(px, py), nx * ex + ny * ey

    def _end_approach_speeds(self, state: tuple, u: tuple) -> tuple:
        """Velocity of each end along the wall's outward unit normal there; > 0 approaching."""
        table = EllipseTable(self.a, self.b)
        speeds = []
        for sign in stick.END_SIGNS:
            px, py, ex, ey = stick.end_motion(state, u, sign * self.ell)
            nx, ny = table.normal_at(px, py)
            speeds.append((nx * ex + ny * ey) / jnp.sqrt(nx * nx + ny * ny))
        return tuple(speeds)

    # -- geometry and flight -------------------------------------------------

    @property
    def inverse_inertia(self) -> jax.Array:
        """``1/I``; zero where the spin is never kicked (static stick, point)."""
        if self.kind == "rotor":
            return 1.0 / self.inertia
        return jnp.zeros_like(self.inertia)

    def direction(self, state: jax.Array) -> jax.Array:
        """The stick's unit vector ``u = (cos alpha, sin alpha)``, shape ``(..., 2)`` (``(1, 0)`` for a point)."""
        return jnp.stack(stick.direction(self.kind == "point", state[..., 2]), axis=-1)

    def end_points(self, state: jax.Array, u: jax.Array | None = None) -> jax.Array:
        """Ends ``[P1, P2]``, shape ``(..., 2, 2)``."""
        c = state[..., 0:2]
        u = self.direction(state) if u is None else u
        offset = self.ell[..., None] * u
        return jnp.stack([c + offset, c - offset], axis=-2)

    def gaps(self, state: jax.Array, u: jax.Array | None = None) -> jax.Array:
        """Contact gaps ``ab - P_k^T D P_k`` of both ends, shape ``(..., 2)``; >= 0 inside."""
        u = self.direction(state) if u is None else u
        return jnp.stack(self._end_gaps(components(state), components(u)), axis=-1)

    def flight(self, state: jax.Array, t: jax.Array) -> jax.Array:
        """Free flight for time ``t``; ``alpha`` wrapped into ``[-pi, pi)`` (see ``StickInCircle.flight``)."""
        return stacked(stick.flight(self.kind != "static", components(state), t))

    def approach_speeds(self, state: jax.Array, u: jax.Array | None = None) -> jax.Array:
        """Velocity of each end along the wall's outward unit normal there, shape ``(..., 2)``; > 0 approaching."""
        u = self.direction(state) if u is None else u
        return jnp.stack(self._end_approach_speeds(components(state), components(u)), axis=-1)

    # -- the impulse law ------------------------------------------------------

    def kick(self, state: tuple, end, u: tuple) -> tuple:
        """Elastic frictionless impulse at end ``end`` (+1 or -1) on the wall: the mass-metric reflection (components).

        ``stick.reflect`` about ``N = D P`` (the table's ``-grad g / 2``) scaled
        by ``sqrt(pi/2 / (ab))``: any positive factor gives the same impulse;
        this one keeps ``|N|^2`` near ``pi/2``, and equals
        ``StickInCircle.kick``'s for ``a = b``.
        """
        x, y = state[0], state[1]
        ux, uy = u
        arm = end * self.ell
        p, q = self.table.metric
        scale = math.sqrt(stick.KICK_NORMAL_SQUARED) / jnp.sqrt(self.gap_scale)
        normal = (scale * p) * (x + arm * ux), (scale * q) * (y + arm * uy)
        return stick.reflect(state, arm, u, normal, self.mass * self.inverse_inertia)

    # -- collision times --------------------------------------------------------

    def next_contact(self, state: jax.Array, static_direction: jax.Array | None = None):
        """``(t, index, ok)``: time to the next contact (``inf`` if none), which end (0: P1, 1: P2), and
        ``ok = False`` if the root search hit its step bound. Differentiable (implicitly, for the search)."""
        parts = components(state)
        if self.kind == "rotor":
            return searched_contact_time(self, parts)
        direction = self.orbit_constants(parts) if static_direction is None else components(static_direction)
        t, index = self.closed_form_contact(parts, direction)
        return t, index, jnp.array(True)

    # -- invariants and watched quantities ----------------------------------------

    def energy(self, state: jax.Array | np.ndarray) -> jax.Array:
        """``M |v|^2 / 2 + I omega^2 / 2`` (the static stick drops the spin term: omega = 0)."""
        vx, vy, omega = (component(state, i) for i in (3, 4, 5))
        e = 0.5 * self.mass * (vx**2 + vy**2)
        if self.kind == "static":
            return e
        return e + stick.spin_term(self.kind == "point", omega, 0.5 * self.inertia * omega**2)

    def angular_momentum(self, state: jax.Array | np.ndarray) -> jax.Array:
        """Angular momentum about the table's centre, ``M (x vy - y vx) + I omega``, shape ``(...)``.

        Conserved only for ``a = b``: elsewhere the wall's normal misses the
        origin and each impulse exerts a torque about it. The static stick
        returns the orbital part only.
        """
        x, y, vx, vy = state[..., 0], state[..., 1], state[..., 3], state[..., 4]
        orbital = self.mass * (x * vy - y * vx)
        if self.kind == "static":
            return orbital
        return orbital + stick.spin_term(self.kind == "point", state[..., 5], self.inertia * state[..., 5])

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

    # == analysis (tangent maps, Lyapunov spectra: jaxbill._engine.tangent) =====================

    @property
    def dynamical_indices(self) -> tuple[int, ...]:
        """All six for a spinning stick; ``(x, y, vx, vy)`` for the static stick and the point."""
        if self.kind == "rotor":
            return (0, 1, 2, 3, 4, 5)
        return (0, 1, 3, 4)

    def phase_velocity(self, state: jax.Array) -> jax.Array:
        """The flow's vector field during free flight, ``[vx, vy, omega, 0, 0, 0]``, shape ``(..., 6)``."""
        state = jnp.asarray(state)
        return jnp.concatenate([state[..., 3:6], jnp.zeros_like(state[..., 0:3])], axis=-1)

    # -- what the analyses ask (jaxbill._scenes.protocols's capability protocols) ---------------------

    sections: ClassVar[tuple[str, ...]] = SECTIONS
    section_axis_labels: ClassVar[dict[str, tuple[str, str]]] = SECTION_AXIS_LABELS
    # Area-preserving for the point (ell = 0); for a stick a projection (jaxbill._scenes.ellipse.sections).
    area_preserving_section: ClassVar[str] = "birkhoff"
    # No continuous symmetry: a periodic orbit closes in every coordinate.
    periodic_symmetry: ClassVar[str] = "none"
    symplectic_flow: ClassVar[bool] = True  # HasSymplecticFlow: elastic and Hamiltonian
    # The state's angles, compared modulo 2 pi when an orbit closes.
    periodic_angles: ClassVar[tuple[int, ...]] = (2,)

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

    def checker_flight(self) -> ColumnFlight:
        """The column ``g_k(x, y, z / sqrt(I/M)) >= 0`` in ``(x, y, z = sqrt(I/M) alpha)`` (``HasCheckerFlight``).

        The gaps' Hessian in the contact point is ``-2 D``, ``|D| = max(a, b) / min(a, b)``; the centre
        of a stick with both ends inside the convex table is inside it, ``|c| <= max(a, b)``.
        """
        turning = self.kind == "rotor"
        scale = jnp.sqrt(self.inertia / self.mass) if turning else jnp.ones_like(self.a)
        major, minor = jnp.maximum(self.a, self.b), jnp.minimum(self.a, self.b)
        return ColumnFlight(
            scene=self,
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
        box = (float(self.a), float(self.b))
        return table_shell_candidates(self, rng, count, energy, angular_momentum, margin, box=box)
