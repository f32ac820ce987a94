"""The stick in a circle: geometry, free flight, contact gaps and the impulse law.

State layout (float64, shape ``(6,)``)::

    [x, y, alpha, vx, vy, omega]

``(x, y)`` is the stick's centre (length units), ``alpha`` the angle of end P1
from the x axis (radians), ``(vx, vy)`` the centre's velocity and ``omega`` the
spin (radians per time unit). The ends are ``P1 = c + ell u`` (contact ``+1``)
and ``P2 = c - ell u`` (contact ``-1``), ``u = (cos alpha, sin alpha)``.
"""

from __future__ import annotations

import math
from functools import partial
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike

from jaxbill._analysis.chaos import circle_shell_candidates
from jaxbill._check.checker import ColumnFlight
from jaxbill._engine.first_root import RootBounds, first_smallest
from jaxbill._engine.step import components, cos_sin, stacked
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
from jaxbill._scenes.circle.sections import (
    CIRCLE_CHART,
    SECTION_AXIS_LABELS,
    birkhoff_section,
    paper_section,
    reduced_section,
    section_state,
)
from jaxbill._scenes.protocols import WALL_TOLERANCE, SectionChart, chosen_section, component

# Orbits of a batch on a CPU run in lanes of this many, one lane after another: a
# vmapped root search waits for its slowest orbit, a narrow lane leaves the vector
# units idle (16 measured best for a spinning stick, benchmarks/bench_drivers.py).
_BATCH_CHUNK = {"rotor": 16, "lens": 256, "circle": 256}

KINDS = ("rotor", "lens", "circle")


def _checked_parameters(R, ell, mass, inertia):
    """Validate concrete parameters; return them broadcast to one shape, and the scene kind."""
    R, ell, mass = (real_parameter(name, v) for name, v in (("R", R), ("ell", ell), ("mass", mass)))
    if inertia is not None:
        inertia = real_parameter("inertia", inertia)
    broadcast_parameters(R=R, ell=ell, mass=mass, inertia=inertia)
    for name, v in (("R", R), ("ell", ell), ("mass", mass)):
        check_parameter(name, v, np.isfinite(v), "finite")
    check_parameter("R", R, R > 0, "> 0")
    check_parameter("ell", ell, ell >= 0, ">= 0")
    check_parameter("ell", ell, ell < R, "< R (the stick must fit inside the circle)")
    check_parameter("mass", mass, mass > 0, "> 0")
    circle = bool(np.all(ell == 0))
    if not circle and np.any(ell == 0):
        raise ValueError("ell must be all zero or all positive within one batch of scenes")
    if inertia is None:
        inertia = mass * ell**2
    else:
        check_parameter("inertia", inertia, ~np.isnan(inertia), "a number or inf, not NaN")
        # The circle's spin is a free rotor, but its energy still counts: its
        # inertia must be valid too.
        check_parameter("inertia", inertia, inertia > 0, "> 0 (or inf for the static lens)")
    lens = (not circle) and bool(np.all(np.isinf(inertia)))
    if not circle and not lens and np.any(np.isinf(inertia)):
        raise ValueError("inertia must be all finite or all inf within one batch of scenes")
    kind = "circle" if circle else ("lens" if lens else "rotor")
    return (*np.broadcast_arrays(R, ell, mass, inertia), kind)


class StickInCircle(eqx.Module):
    """A stick of half-length ``ell`` bouncing elastically inside a fixed circle.

    Args:
        R: radius of the circle, ``R > 0``.
        ell: half-length of the stick, ``0 <= ell < R``. ``ell = 0`` is the
            circle billiard (the spin decouples).
        mass: total mass ``M > 0`` (default 1).
        inertia: moment of inertia about the centre, ``I > 0``. ``None`` means
            ``mass * ell**2`` (two point masses ``M/2`` at the ends);
            ``float('inf')`` is the static-lens limit (the stick never turns:
            ``omega`` must then be 0). For ``ell = 0`` the spin is a free
            rotor and the inertia only weighs it in ``energy``.

    Parameters may be arrays of one common shape ``(B,)`` (scalars broadcast) to
    make a batch of scenes for ``jax.vmap(..., in_axes=(0, ...))``.

    The leaves ``R, ell, mass, inertia`` are differentiable. ``kind`` is static
    and chooses the compiled code: ``"lens"`` (infinite inertia) and
    ``"circle"`` (``ell = 0``) have closed-form collision times (quadratics);
    ``"rotor"`` (finite inertia) uses the safe-step root finder.
    """

    R: jax.Array
    ell: jax.Array
    mass: jax.Array
    inertia: jax.Array
    kind: str = eqx.field(static=True)

    state_size: ClassVar[int] = 6
    state_layout: ClassVar[str] = "[x, y, alpha, vx, vy, omega]"
    gap_names: ClassVar[tuple[str, ...]] = ("end P1", "end P2")
    wall_name: ClassVar[str] = "the circle"

    def __init__(
        self,
        R: ArrayLike,
        ell: ArrayLike,
        mass: ArrayLike = 1.0,
        inertia: ArrayLike | None = None,
        *,
        kind: str | None = None,
    ):
        require_x64()  # float32 leaves would void every accuracy claim
        leaves = [R, ell, mass] + ([] if inertia is None else [inertia])
        if all(is_concrete(v) for v in leaves):
            R, ell, mass, inertia, guessed = _checked_parameters(R, ell, mass, inertia)
        else:
            # Traced parameters (a scene built inside jit): values cannot be
            # checked here; invalid ones poison the results with NaN instead.
            if inertia is None:
                inertia = mass * ell**2
            lens_literal = isinstance(inertia, float) and math.isinf(inertia)
            guessed = "lens" if lens_literal else "rotor"
        self.R, self.ell, self.mass, self.inertia = (jnp.asarray(v, dtype=jnp.float64) for v in (R, ell, mass, inertia))
        if kind is not None and kind not in KINDS:
            raise ValueError(f"kind must be one of {KINDS}; got {kind!r}")
        self.kind = guessed if kind is None else kind

    def check(self) -> None:
        """Raise ValueError if the parameters are invalid or do not fit ``kind``.

        The constructor checks; this re-checks a scene whose leaves were
        replaced afterwards (``eqx.tree_at``, an optimiser step).
        """
        # The circle's default inertia, M ell^2 = 0, is stored as 0 (its spin
        # weighs nothing); given explicitly, an inertia must be > 0.
        default = self.kind == "circle" and is_concrete(self.inertia) and np.all(np.asarray(self.inertia) == 0)
        *_, kind = _checked_parameters(self.R, self.ell, self.mass, None if default else self.inertia)
        if kind != self.kind:
            raise ValueError(
                f"the parameters describe a {kind!r} scene but this scene was compiled as "
                f"{self.kind!r} (inertia = inf is the lens, ell = 0 the circle): build a new StickInCircle"
            )

    # -- what the collision engine asks of a scene (see jaxbill._scenes.protocols) -------

    @property
    def batch_chunk(self) -> int:
        return _BATCH_CHUNK[self.kind]

    @property
    def gap_scale(self) -> jax.Array:
        return self.R**2

    @property
    def contact_codes(self) -> tuple[int, ...]:
        return stick.contact_codes(self.kind == "circle")

    def check_state_values(self, state: np.ndarray) -> None:
        R = np.asarray(self.R)
        if R.ndim and state.ndim == 2 and R.shape[0] != state.shape[0]:
            raise ValueError(
                f"a batch of {R.shape[0]} scenes needs a batch of {R.shape[0]} states; got {state.shape[0]}"
            )
        if self.kind == "lens" and np.any(state[..., 5] != 0):
            raise ValueError(
                "omega must be 0 for the static lens (inertia = inf): an infinitely heavy stick cannot spin"
            )

    def is_valid(self, state: jax.Array) -> jax.Array:
        params_ok = (
            (self.R > 0)
            & (self.ell >= 0)
            & (self.ell < self.R)
            & (self.mass > 0)
            & jnp.isfinite(self.R)
            & jnp.isfinite(self.mass)
        )
        if self.kind == "rotor":
            params_ok &= (self.inertia > 0) & jnp.isfinite(self.inertia)
        elif self.kind == "circle":
            params_ok &= self.inertia >= 0  # 0: the default M ell^2; inf: a spin that never changes
        state_ok = jnp.all(jnp.isfinite(state)) & self.motion_is_representable(state)
        gaps = self.gaps(state)
        inside = jnp.all(gaps >= -WALL_TOLERANCE * self.R**2)
        # An end on the wall that does not move inwards is refused eagerly; a
        # tangential one would stall the map (zero-length flights), so poison.
        inside &= ~on_wall_not_inwards(gaps, self.approach_speeds(state))
        ok = params_ok & state_ok & inside
        if self.kind == "lens":
            ok &= state[5] == 0.0
        return ok

    def motion_is_representable(self, state) -> jax.Array:
        """Traceable: ``|v|^2``, ``omega^2`` and the energy are ordinary float64 numbers.

        See ``jaxbill._engine.validation``.
        """
        return motion_is_representable(state[..., 3:5], state[..., 5] ** 2, self.energy(state), self.R)

    def orbit_constants(self, state0: tuple):
        """The static lens never turns: its direction ``(ux, uy)`` serves a whole orbit (``state0``: components)."""
        return stick.direction(self.kind == "circle", state0[2]) if self.kind == "lens" else None

    # -- the engine's questions (see jaxbill._engine.step) -----------------------------
    # States are components (x, y, alpha, vx, vy, omega): scalars, or arrays of
    # one shape (a block of orbits inside a kernel); results are tuples.

    @property
    def searches_for_roots(self) -> bool:
        """A spinning stick's gaps are transcendental in time; the lens's and the circle's are quadratics."""
        return self.kind == "rotor"

    def root_search(self, state: tuple):
        """``(profile, RootBounds)`` of the flight from ``state`` (the profile is the state itself)."""
        return state, _rotor_bounds(self, state)

    def gaps_along_flight(self, state: tuple, t: jax.Array):
        """Both ends' gaps ``R^2 - |P_k|^2`` and their first and second time derivatives after a flight
        of ``t`` (2-tuples)."""
        x, y, alpha, vx, vy, omega = state
        cx, cy = x + vx * t, y + vy * t
        cu, su = cos_sin(alpha + omega * t)
        centre_gap = self.R**2 - self.ell**2 - (cx * cx + cy * cy)
        centre_slope = -2.0 * (cx * vx + cy * vy)
        centre_curvature = -2.0 * (vx * vx + vy * vy)
        along_unit = cx * cu + cy * su  # c . u
        along = 2.0 * self.ell * along_unit
        along_slope = 2.0 * self.ell * (vx * cu + vy * su + omega * (cy * cu - cx * su))
        # (c . u)'' = 2 omega v . u_perp - omega^2 c . u
        along_curvature = 2.0 * self.ell * (omega * (2.0 * (vy * cu - vx * su) - omega * along_unit))
        return (
            (centre_gap - along, centre_gap + along),
            (centre_slope - along_slope, centre_slope + along_slope),
            (centre_curvature - along_curvature, centre_curvature + along_curvature),
        )

    def closed_form_contact(self, state: tuple, lens_direction):
        """``(t, index)`` for the lens and the circle: each end (the centre) moves on a line."""
        x, y, _, vx, vy, _ = state
        if self.kind == "circle":
            t = _exit_time(x, y, vx, vy, self.R)
            return t, jnp.zeros(jnp.shape(t), jnp.int32)
        ux, uy = lens_direction
        t_p1 = _exit_time(x + self.ell * ux, y + self.ell * uy, vx, vy, self.R)
        t_p2 = _exit_time(x - self.ell * ux, y - self.ell * uy, vx, vy, self.R)
        return jnp.minimum(t_p1, t_p2), first_smallest((t_p1, t_p2))

    def collide_at(self, state: tuple, t: jax.Array, index: jax.Array, lens_direction):
        """The flight to ``t`` and the impulse(s) of end ``index`` (0: P1, 1: P2) touching the wall."""
        moved = stick.flight(self.kind != "lens", state, t)
        if self.kind == "lens":
            u = lens_direction  # the lens never turns: one u serves the whole orbit
        else:
            u = stick.direction(self.kind == "circle", moved[2])
        if self.kind == "circle":
            return self.kick(moved, 0.0, u), jnp.ones(jnp.shape(t), jnp.int32)
        return self._resolve_contact(moved, index, u)

    def _resolve_contact(self, state: tuple, index: jax.Array, u: tuple):
        """Apply the impulse at the touching end; a simultaneous second contact too (a lens corner)."""
        return stick.resolve_two_ends(
            self.kick,
            partial(_end_gap_and_closing, self),
            partial(_end_approach_speeds, self),
            state,
            index,
            u,
            self.R**2,
        )

    # -- derived quantities --------------------------------------------------

    @property
    def inverse_inertia(self) -> jax.Array:
        """``1/I``; zero where the spin is never kicked (lens, circle)."""
        if self.kind == "rotor":
            return 1.0 / self.inertia
        return jnp.zeros_like(self.inertia)

    # -- geometry and flight -------------------------------------------------

    def direction(self, state: jax.Array) -> jax.Array:
        """The stick's unit vector ``u = (cos alpha, sin alpha)``, shape ``(..., 2)``.

        Every geometric method takes it as an optional argument ``u``: the
        static lens never turns, so an orbit computes it once rather than at
        every collision (float64 sin/cos dominate the lens's cost), and the
        circle (``ell = 0``) never needs it.
        """
        return jnp.stack(stick.direction(self.kind == "circle", state[..., 2]), axis=-1)

    def end_points(self, state: jax.Array, u: jax.Array | None = None) -> jax.Array:
        """Ends ``[P1, P2]``, shape ``(..., 2, 2)``."""
        c = state[..., 0:2]
        u = self.direction(state) if u is None else u
        offset = self.ell[..., None] * u
        return jnp.stack([c + offset, c - offset], axis=-2)

    def gaps(self, state: jax.Array, u: jax.Array | None = None) -> jax.Array:
        """Contact gaps ``R^2 - |P_k|^2`` of both ends, shape ``(..., 2)``; >= 0 inside."""
        u = self.direction(state) if u is None else u
        return jnp.stack(_end_gaps(self, components(state), components(u)), axis=-1)

    def flight(self, state: jax.Array, t: jax.Array) -> jax.Array:
        """Free flight for time ``t``; ``alpha`` is wrapped into ``[-pi, pi)``.

        Wrapping keeps ``cos``/``sin`` of ``alpha`` exact to rounding however
        long the run: an unwrapped angle of ``1e7`` radians would carry ``1e-9``
        absolute error into every contact.
        """
        return stacked(stick.flight(self.kind != "lens", components(state), t))

    def approach_speeds(self, state: jax.Array, u: jax.Array | None = None) -> jax.Array:
        """Normal velocity of each end towards the wall, ``v . n + omega s_k``, shape ``(..., 2)``."""
        u = self.direction(state) if u is None else u
        return jnp.stack(_end_approach_speeds(self, components(state), components(u)), axis=-1)

    # -- the impulse law ------------------------------------------------------

    def kick(self, state: tuple, end, u: tuple) -> tuple:
        """Elastic frictionless impulse at end ``end`` (+1 or -1) touching the wall (components in and out).

        ``stick.reflect`` (every table's impulse) about the normal ``P``:
        ``n = P/|P|``, ``s = end ell (u x n)``, ``v_n = v . n + omega s``,
        ``J = 2 v_n / (1/M + s^2/I)``, ``v' = v - (J/M) n``,
        ``omega' = omega - (J/I) s``. Energy and the angular momentum about the
        origin are conserved exactly (the impulse is radial).

        Computed along the unnormalised normal ``P`` itself, with ``|P|^2`` in
        the denominator: that impulse is exactly elastic for whatever vector
        rounding produced, where a rounded unit normal would bias the energy
        by about an ulp per collision, the same sign each time. In the form
        ``dv = -w n``, ``d omega = -w (M/I) s`` with ``w = J/M = 2 v_n / (|n|^2 +
        (M/I) s^2)``, the mass enters only through the one ratio ``M/I``.

        ``n`` is ``P`` scaled by ``sqrt(c) / R`` (any factor gives the same
        impulse in exact arithmetic), so that ``|n|^2`` sits near
        ``c = pi / 2`` rather than near ``R^2``: at a contact ``|P|^2 = R^2``
        to a few ulps, and when that is a power of two (``R = 2``) the
        quotient ``2 v_n / |P|^2`` rounds to ``v_n / 2`` exactly whatever those
        ulps are; the rounding of the contact point, which the division would
        otherwise compensate, then biased the energy by about 0.2 ulp per
        collision (5e-17 relative at ``R = 2``). ``c`` is mid-binade and ``1/c``
        has no short binary period (unlike ``1.5``, whose quotients repeat
        with period 3), so the quotient's rounding is unbiased. (Applying a
        rounded ``1/M`` twice, in the denominator and in ``dv``, kept a bias
        of the same size for ``M = 3``: hence the single ratio ``M/I``.)
        Measured over 1e6 collisions: below 5e-18 per collision, against
        1e-17 to 1.3e-16 before, for the lens, the circle and spinning sticks.
        """
        x, y = state[0], state[1]
        ux, uy = u
        arm = end * self.ell
        scale = math.sqrt(stick.KICK_NORMAL_SQUARED) / self.R
        normal = scale * (x + arm * ux), scale * (y + arm * uy)
        # M / I is 0 for the lens and the circle: their spin is never kicked
        return stick.reflect(state, arm, u, normal, self.mass * self.inverse_inertia)

    # -- invariants ---------------------------------------------------------------

    def energy(self, state: jax.Array | np.ndarray) -> jax.Array:
        """``M |v|^2 / 2 + I omega^2 / 2`` (the lens drops the spin term: omega = 0).

        ``state``: an array ``(..., 6)`` or its components (``jaxbill._scenes.protocols.component``).
        """
        vx, vy, omega = (component(state, i) for i in (3, 4, 5))
        e = 0.5 * self.mass * (vx**2 + vy**2)
        if self.kind == "lens":
            return e
        return e + stick.spin_term(self.kind == "circle", omega, 0.5 * self.inertia * omega**2)

    def angular_momentum(self, state: jax.Array | np.ndarray) -> jax.Array:
        """Total angular momentum about the origin, ``M (x vy - y vx) + I omega``.

        Conserved: the wall force is radial. For the static lens (``I = inf``)
        only the orbital part is returned, and it is *not* conserved: the
        infinitely heavy stick absorbs the torque.
        """
        x, y, vx, vy = state[..., 0], state[..., 1], state[..., 3], state[..., 4]
        orbital = self.mass * (x * vy - y * vx)
        if self.kind == "lens":
            return orbital
        return orbital + stick.spin_term(self.kind == "circle", state[..., 5], self.inertia * state[..., 5])

    # == analysis (tangent maps, Lyapunov spectra: jaxbill._engine.tangent) =====================
    # Added for the analysis modules; the engine above does not use these.

    @property
    def dynamical_indices(self) -> tuple[int, ...]:
        """State coordinates that carry the dynamics (see ``jaxbill.dynamical_indices``).

        All six for a spinning stick; ``(x, y, vx, vy)`` for the static lens
        (``alpha`` is a constant parameter, ``omega = 0``) and for the circle
        billiard (the spin is a free rotor decoupled from the centre).
        """
        if self.kind == "rotor":
            return (0, 1, 2, 3, 4, 5)
        return (0, 1, 3, 4)

    def phase_velocity(self, state: jax.Array) -> jax.Array:
        """The flow's vector field during free flight, ``[vx, vy, omega, 0, 0, 0]``, shape ``(..., 6)``."""
        state = jnp.asarray(state)
        return jnp.concatenate([state[..., 3:6], jnp.zeros_like(state[..., 0:3])], axis=-1)

    # -- what the analyses ask (jaxbill._scenes.protocols's capability protocols) ---------------------

    sections: ClassVar[tuple[str, ...]] = ("reduced", "paper", "birkhoff")
    section_axis_labels: ClassVar[dict[str, tuple[str, str]]] = SECTION_AXIS_LABELS
    area_preserving_section: ClassVar[str] = "reduced"
    periodic_symmetry: ClassVar[str] = "rotation"  # turning the whole picture about the centre
    symplectic_flow: ClassVar[bool] = True  # HasSymplecticFlow: elastic and Hamiltonian

    def section(self, states: jax.Array, contacts: jax.Array | None = None, name: str | None = None) -> jax.Array:
        """Section points ``(..., 2)`` (``HasSection``): ``"reduced"`` (default, area-preserving at fixed
        ``E, L``: ``jb.reduced_section``), ``"paper"`` (``jb.paper_section``) or ``"birkhoff"``
        (``jb.birkhoff_section``, fixed walls only). ``contacts`` is not needed: the touching end
        is the one with the smaller gap."""
        del contacts
        functions = {"reduced": reduced_section, "paper": paper_section, "birkhoff": birkhoff_section}
        return functions[chosen_section(self, name)](self, states)

    def section_state(self, point: ArrayLike, energy=0.5, angular_momentum=0.0) -> jax.Array:
        """The state ``(..., 6)`` just after a collision at the reduced section's ``point = (s, p)``,
        shape ``(..., 2)``, at energy ``E`` and angular momentum ``L`` (``jb.section_state``)."""
        xy = jnp.asarray(point, dtype=jnp.float64)
        return section_state(self, xy[..., 0], xy[..., 1], energy, angular_momentum)

    @property
    def section_chart(self) -> SectionChart:
        """The explorer's chart of the reduced section."""
        return CIRCLE_CHART

    def checker_flight(self) -> ColumnFlight:
        """The spiral column ``r <= b(theta - alpha)`` in ``(x, y, sqrt(I/M) alpha)`` (``HasCheckerFlight``)."""
        turning = self.kind == "rotor"
        scale = jnp.sqrt(self.inertia / self.mass) if turning else jnp.ones_like(self.R)
        return ColumnFlight(
            scene=self,
            scale=scale,
            length=self.R,
            reach=jnp.sqrt(self.R**2 - self.ell**2),
            hessian_bound=jnp.ones_like(self.R),
            frozen=self.kind == "lens",
            single_sheet=self.kind == "circle",
        )

    def sample_states(self, rng, count: int, energy: float, angular_momentum=None, margin: float = 1e-9):
        """``count`` tries at Liouville-distributed states on the shell ``E`` (and ``L`` if given)
        (``SamplesStates``): ``(states (k, 6), weights (k,))``, see ``jb.sample_energy_shell``."""
        return circle_shell_candidates(self, rng, count, energy, angular_momentum, margin)

    # == end of analysis block ============================================================


def _end_gaps(scene: StickInCircle, state: tuple, u: tuple) -> tuple:
    """``R^2 - |P_k|^2`` of ends P1 and P2."""
    return tuple(_end_gap_and_closing(scene, state, u, sign)[0] for sign in stick.END_SIGNS)


def _end_approach_speeds(scene: StickInCircle, state: tuple, u: tuple) -> tuple:
    """Normal velocity ``v . n + omega s_k`` of ends P1 and P2 towards the wall."""
    speeds = []
    for sign in stick.END_SIGNS:
        px, py, ex, ey = stick.end_motion(state, u, sign * scene.ell)
        speeds.append((px * ex + py * ey) / jnp.sqrt(px * px + py * py))
    return tuple(speeds)


def _end_gap_and_closing(scene: StickInCircle, state: tuple, u: tuple, sign) -> tuple:
    """The gap ``R^2 - |P|^2`` of the end ``P = c + sign ell u`` and ``P . dP/dt``, its approach speed times ``|P|``."""
    px, py, ex, ey = stick.end_motion(state, u, sign * scene.ell)
    return scene.R**2 - (px * px + py * py), px * ex + py * ey


def _exit_time(px, py, vx, vy, radius):
    """First ``t >= 0`` with ``|p + v t| = radius`` while moving outwards.

    ``p`` is inside (or on, to rounding) the disc. A point on the rim moving
    inwards gets the far root, never ``t = 0``; one on or outside the rim moving
    outwards gets 0. Never-moving points get ``inf``.
    """
    speed2 = vx * vx + vy * vy
    b = px * vx + py * vy
    gap = radius * radius - (px * px + py * py)
    disc = b * b + speed2 * gap
    root = jnp.sqrt(jnp.maximum(disc, 0.0))
    # Cancellation-free forms of the larger root of speed2 t^2 + 2 b t - gap = 0.
    # A point outside by rounding (gap < 0) whose line misses the disc
    # (disc < 0: a grazing chord shorter than rounding) takes the chord of
    # the tangent line through it, as if on the rim: ``-2 b / speed2``. The
    # clamped root would give the chord's midpoint, where the kick is zero and
    # every later flight has length 0.
    # Each form is a quotient: the numerator and denominator are chosen, then
    # divided once (the chosen quotient, to the bit, at a third of the divisions).
    inward = jnp.where(disc < 0.0, -2.0 * b, root - b)
    outward = b > 0.0
    t = jnp.where(outward, gap, inward) / jnp.where(outward, b + root, speed2)
    return jnp.where(speed2 > 0.0, jnp.maximum(t, 0.0), jnp.inf)


def _disc_crossing(px, py, vx, vy, radius):
    """Interval ``(t_in, t_out)`` of ``t >= 0`` with ``|p + v t| < radius`` (empty if none)."""
    speed2 = vx * vx + vy * vy
    b = px * vx + py * vy
    excess = px * px + py * py - radius * radius
    disc = b * b - speed2 * excess
    root = jnp.sqrt(jnp.maximum(disc, 0.0))
    # Roots of speed2 t^2 + 2 b t + excess = 0 without cancellation.
    q = -(b + jnp.where(b < 0.0, -root, root))
    t1, t2 = q / speed2, excess / q
    t_in, t_out = jnp.minimum(t1, t2), jnp.maximum(t1, t2)
    crosses = (speed2 > 0.0) & (disc > 0.0) & (t_out > 0.0)
    inside_for_ever = (speed2 == 0.0) & (excess < 0.0)
    t_in = jnp.where(crosses, jnp.maximum(t_in, 0.0), jnp.where(inside_for_ever, 0.0, jnp.inf))
    t_out = jnp.where(crosses, t_out, jnp.inf)
    return t_in, t_out


def _rotor_bounds(scene: StickInCircle, state: tuple) -> RootBounds:
    x, y, _, vx, vy, omega = state
    speed = jnp.sqrt(vx * vx + vy * vy)
    spin = jnp.abs(omega)
    # No end can touch while the centre is within R - ell of the origin (the
    # quiet interval); before the first contact the centre stays within
    # sqrt(R^2 - ell^2).
    centre_radius = jnp.sqrt(x * x + y * y)
    quiet_in, quiet_out = _disc_crossing(x, y, vx, vy, scene.R - scene.ell)
    reach = jnp.maximum(jnp.sqrt(scene.R**2 - scene.ell**2), centre_radius)
    # g_k'' = -2|v|^2 - 2 k ell W'' with |W''| <= 2 |omega| |v| + omega^2 |c(t)|.
    wobble = 2.0 * scene.ell * (2.0 * spin * speed + spin * spin * reach)
    lower_curv = 2.0 * speed * speed + wobble
    upper_curv = wobble - 2.0 * speed * speed
    # g_k''' = -2 k ell W''' with |W'''| <= 3 omega^2 |v| + |omega|^3 |c(t)|.
    jerk = 2.0 * scene.ell * (spin * spin * (3.0 * speed + spin * reach))
    # Resolve the root finely enough for both the position (|v| dt << R) and
    # the angle (|omega| dt << 1 rad, whatever ell is).
    time_scale = 1.0 / (speed / scene.R + spin)
    return RootBounds(lower_curv, upper_curv, quiet_in, quiet_out, time_scale, jerk)
