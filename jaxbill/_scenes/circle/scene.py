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
from typing import ClassVar, cast

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike

from jaxbill._engine.step import cos_sin
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
from jaxbill._scenes.circle.sections import (
    CIRCLE_CHART,
    SECTION_AXIS_LABELS,
    birkhoff_section,
    paper_section,
    reduced_section,
    section_state,
)
from jaxbill._scenes.protocols import NO_CONTACT, SEVERAL_CONTACTS, SectionChart, StickColumn, chosen_section
from jaxbill._scenes.shell_sampling import circle_shell_candidates
from jaxbill._scenes.tables.circle import Circle

# Orbits of a batch on a CPU run in lanes of this many, one lane after another: a
# vmapped root search waits for its slowest orbit, a narrow lane leaves the vector
# units idle (16 measured best for a spinning stick, benchmarks/bench_drivers.py).
_BATCH_CHUNK = {"rotor": 16, "lens": 256, "circle": 256}

KINDS = ("rotor", "lens", "circle")
# The body's kind for each of the scene's: the lens is a stick that never turns, the circle a point.
_BODY_KIND = {"rotor": "rotor", "lens": "static", "circle": "point"}


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


class StickInCircle(BodyInTable):
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

    state_size: ClassVar[int] = 6
    state_layout: ClassVar[str] = "[x, y, alpha, vx, vy, omega]"
    gap_names: ClassVar[tuple[str, ...]] = ("end P1", "end P2")
    wall_name: ClassVar[str] = "the circle"
    never_turning: ClassVar[str] = "the static lens"

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
        if kind is not None and kind not in KINDS:
            raise ValueError(f"kind must be one of {KINDS}; got {kind!r}")
        kind = guessed if kind is None else kind
        if kind == "circle":
            body = PointBody(jnp.asarray(mass, jnp.float64), jnp.asarray(inertia, jnp.float64))
        else:
            body = Dumbbell(jnp.asarray(ell, jnp.float64), None, mass, inertia, kind=_BODY_KIND[kind])
        super().__init__(body, Circle(R))

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

    # -- the parameters -----------------------------------------------------------------

    @property
    def kind(self) -> str:
        """``"rotor"``, ``"lens"`` (infinite inertia) or ``"circle"`` (``ell = 0``): static."""
        return {"rotor": "rotor", "static": "lens", "point": "circle"}[self.body.kind]

    @property
    def R(self) -> jax.Array:
        """The circle's radius."""
        return cast(Circle, self.table).R

    @property
    def ell(self) -> jax.Array:
        """The stick's half-length (0 for the circle billiard)."""
        return jnp.zeros_like(cast(Circle, self.table).R) if self.body.kind == "point" else cast(Dumbbell, self.body).l1

    @property
    def batch_chunk(self) -> int:
        return _BATCH_CHUNK[self.kind]

    @property
    def gap_codes(self) -> tuple[int, ...]:
        """End P1 touching is contact ``+1``, end P2 ``-1``."""
        return (1,) if self.kind == "circle" else (1, -1)

    @property
    def contact_codes(self) -> tuple[int, ...]:
        return (NO_CONTACT, 1) if self.kind == "circle" else (-1, NO_CONTACT, 1, SEVERAL_CONTACTS)

    @property
    def inverse_inertia(self) -> jax.Array:
        """``1/I``; zero where the spin is never kicked (lens, circle)."""
        if self.kind == "rotor":
            return 1.0 / self.inertia
        return jnp.zeros_like(self.inertia)

    # -- the stick's own geometry --------------------------------------------------------

    def direction(self, state: jax.Array) -> jax.Array:
        """The stick's unit vector ``u = (cos alpha, sin alpha)``, shape ``(..., 2)`` (``(1, 0)`` for a point)."""
        alpha = jnp.asarray(state)[..., 2]
        if self.kind == "circle":
            return jnp.stack([jnp.ones_like(alpha), jnp.zeros_like(alpha)], axis=-1)
        return jnp.stack(cos_sin(alpha), axis=-1)

    def end_points(self, state: jax.Array) -> jax.Array:
        """Ends ``[P1, P2]``, shape ``(..., 2, 2)`` (both at the centre for the circle billiard)."""
        c = jnp.asarray(state)[..., 0:2]
        offset = self.ell[..., None] * self.direction(state)
        return jnp.stack([c + offset, c - offset], axis=-2)

    def kick(self, state: tuple, end, u: tuple) -> tuple:
        """The elastic frictionless impulse at end ``end`` (+1: P1, -1: P2) touching the wall, the stick along
        ``u`` (components in and out): the mass-metric reflection about the radial normal. Energy and the
        angular momentum about the origin are conserved exactly (the impulse is radial)."""
        x, y = state[0], state[1]
        rx, ry = end * self.ell * u[0], end * self.ell * u[1]
        normal = self.table.pieces[0].impulse_normal(x + rx, y + ry)
        tx, ty = self.body.turn_vector(rx, ry)
        return impulse.reflect(state, normal[0] * tx + normal[1] * ty, normal, self.body.mass_ratio)

    # -- what the analyses ask (jaxbill._scenes.protocols's capability protocols) ---------------------

    sections: ClassVar[tuple[str, ...]] = ("reduced", "paper", "birkhoff")
    section_axis_labels: ClassVar[dict[str, tuple[str, str]]] = SECTION_AXIS_LABELS
    area_preserving_section: ClassVar[str] = "reduced"
    periodic_symmetry: ClassVar[str] = "rotation"  # turning the whole picture about the centre

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

    def checker_flight(self) -> StickColumn:
        """The spiral column ``r <= b(theta - alpha)`` in ``(x, y, sqrt(I/M) alpha)`` (``HasCheckerFlight``)."""
        turning = self.kind == "rotor"
        scale = jnp.sqrt(self.inertia / self.mass) if turning else jnp.ones_like(self.R)
        return StickColumn(
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
