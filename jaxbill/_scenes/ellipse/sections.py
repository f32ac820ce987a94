r"""Boundary sections of the stick in an ellipse (``StickInEllipse.section``), and their inverse.

At a collision one end ``P = c + k ell u`` touches the ellipse
``x^2/a^2 + y^2/b^2 = 1``. Write the contact point with its parameter angle
``t`` (the "eccentric anomaly"), ``P = (a cos t, b sin t)``, ``0 <= t < 2 pi``;
the anticlockwise unit tangent there is
``T = (-a sin t, b cos t) / sqrt(a^2 sin^2 t + b^2 cos^2 t)``. Two sections:

* ``"birkhoff"``: ``[s, p]`` with ``s`` the arc length from the end of the
  ``a`` semi-axis ``(a, 0)`` to the contact, anticlockwise,
  ``s(t) = int_0^t sqrt(a^2 sin^2 tau + b^2 cos^2 tau) dtau``
  (``0 <= s < ellipse_length``, length units; an incomplete elliptic
  integral of the second kind, summed here quarter turn by quarter turn with
  64-point Gauss-Legendre quadrature, exact to rounding), and
  ``p = sqrt(M) (v . T) / sqrt(2 E)``, the centre's tangential momentum in
  units of ``sqrt(2 M E)``, dimensionless in ``[-1, 1]``. For a point
  (``ell = 0``) ``p = sin chi``, ``chi`` the angle of the outgoing velocity
  from the inward normal, and ``(s, p)`` are Birkhoff's coordinates: the
  collision map preserves ``ds dp`` (the billiard map is symplectic in arc
  length and tangential momentum), so this is the area-preserving section.
  For a stick it is a projection of a higher-dimensional section (``E`` is
  the only invariant: at fixed ``E`` the section of a turning stick has four
  dimensions) and areas in it mean nothing.
* ``"angle"``: ``[t, p]``, the same with the parameter angle instead of the arc
  length; smooth and cheap, not area-preserving (``ds = |P'(t)| dt``).

For ``a = b = R``, ``t`` is the polar angle ``Phi`` of the contact point, ``s = R Phi`` and
``T = (-sin Phi, cos Phi)``: the point's ``"birkhoff"`` section is the circle's
``jb.birkhoff_section`` and, for any stick, ``p`` is the ``p`` of
``jb.reduced_section`` (``tests/test_ellipse_analyses.py`` checks both).

``section_state`` inverts the Birkhoff section: the state just after a
collision of end P1 at ``(s, p)`` with the stick at a chosen angle to the
wall's outward normal and a chosen spin (a turning stick's section point does
not fix them).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike

from jaxbill._engine.validation import as_states
from jaxbill._scenes.circle.sections import halton
from jaxbill._scenes.protocols import SectionChart, end_points

# Gauss-Legendre nodes and weights on [-1, 1] for the arc length quadrature.
_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(64)
# Newton steps inverting s(t) (quadratic convergence from the linear guess).
_NEWTON_STEPS = 8

SECTIONS = ("birkhoff", "angle")


def _speed_along(scene, t):
    """``|P'(t)| = sqrt(a^2 sin^2 t + b^2 cos^2 t)``: the arc length per unit of the parameter angle."""
    return jnp.sqrt((scene.a * jnp.sin(t)) ** 2 + (scene.b * jnp.cos(t)) ** 2)


def _arc_within_quarter(scene, r: jax.Array) -> jax.Array:
    """``int_0^r |P'(tau)| dtau`` for ``0 <= r <= pi/2`` by 64-point Gauss-Legendre quadrature.

    The integrand's nearest complex singularity is at ``Im tau = artanh(min/max)``
    of the axes; over a quarter turn (half-width ``pi/4``) the rule's error
    falls like ``rho^-128`` with ``rho = d/(pi/4) + sqrt(1 + (d/(pi/4))^2)``:
    below rounding for axis ratios up to about 10 (1e-16 at 10, still 1e-13 at 20).
    """
    half = 0.5 * r[..., None]
    taus = half * (1.0 + jnp.asarray(_NODES))
    return jnp.sum(jnp.asarray(_WEIGHTS) * _speed_along(scene, taus), axis=-1) * half[..., 0]


def arc_length(scene, t: ArrayLike) -> jax.Array:
    """Arc length ``s(t)`` (length) from ``(a, 0)`` anticlockwise to parameter angle ``t`` (radians, any shape).

    Summed by quarter turns: ``|P'|`` has period ``pi`` and is symmetric about
    ``pi/2``, so ``s(t) = k Q + s_k(r)``, ``t = k pi/2 + r``, ``Q`` the quarter
    arc and ``s_k(r) = s(r)`` for even ``k``, ``Q - s(pi/2 - r)`` for odd ``k``;
    each piece is one quadrature over at most a quarter turn (see ``_arc_within_quarter``).
    """
    t = jnp.asarray(t, dtype=jnp.float64)
    quarter_turn = 0.5 * jnp.pi
    k = jnp.floor(t / quarter_turn)
    r = jnp.clip(t - k * quarter_turn, 0.0, quarter_turn)
    quarter = _arc_within_quarter(scene, jnp.full_like(t, quarter_turn))
    odd = jnp.remainder(k, 2.0) == 1.0
    part = jnp.where(odd, quarter - _arc_within_quarter(scene, quarter_turn - r), _arc_within_quarter(scene, r))
    return k * quarter + part


def ellipse_length(scene) -> jax.Array:
    """The perimeter ``4 a E(1 - b^2/a^2)`` (length), as ``arc_length(2 pi)``."""
    return arc_length(scene, 2.0 * jnp.pi)


def parameter_angle(scene, s: jax.Array) -> jax.Array:
    """The inverse of ``arc_length`` on ``[0, ellipse_length)``: ``t`` with ``s(t) = s`` (Newton)."""
    s = jnp.asarray(s, dtype=jnp.float64)
    t = 2.0 * jnp.pi * s / ellipse_length(scene)
    for _ in range(_NEWTON_STEPS):
        t = t - (arc_length(scene, t) - s) / _speed_along(scene, t)
    return t


def contact_end(scene, states: jax.Array, contacts: jax.Array | None = None) -> jax.Array:
    """``+1`` (P1) or ``-1`` (P2): the end on the wall; from ``contacts`` when given (+1/-1), else the smaller gap."""
    gaps = jnp.abs(scene.gaps(states))
    by_gap = jnp.where(gaps[..., 0] <= gaps[..., 1], 1, -1).astype(jnp.int32)
    if contacts is None:
        return by_gap
    contacts = jnp.asarray(contacts)
    return jnp.where((contacts == 1) | (contacts == -1), contacts, by_gap).astype(jnp.int32)


def _contact(scene, states, contacts):
    """Parameter angle ``t`` in ``[0, 2 pi)`` of the touching end and the tangential velocity ``v . T``."""
    end = contact_end(scene, states, contacts)
    u = scene.direction(states)
    point = states[..., 0:2] + (end * scene.ell)[..., None] * u
    t = jnp.remainder(jnp.arctan2(point[..., 1] / scene.b, point[..., 0] / scene.a), 2.0 * jnp.pi)
    tangent_x, tangent_y = -scene.a * jnp.sin(t), scene.b * jnp.cos(t)
    v_t = (tangent_x * states[..., 3] + tangent_y * states[..., 4]) / _speed_along(scene, t)
    return t, v_t


def ellipse_section(scene, states: jax.Array, contacts: jax.Array | None = None, name: str = "birkhoff"):
    """``[s, p]`` (``"birkhoff"``) or ``[t, p]`` (``"angle"``) of states ``(..., 6)`` at collisions: ``(..., 2)``.

    See the module docstring. ``contacts`` ``(...)``: the collisions' contact
    codes (``Orbit.contact``), optional: without them the end with the smaller
    gap is the touching one.
    """
    states = as_states(scene, states)
    t, v_t = _contact(scene, states, contacts)
    p = jnp.sqrt(scene.mass) * v_t / jnp.sqrt(2.0 * scene.energy(states))
    first = arc_length(scene, t) if name == "birkhoff" else t
    return jnp.stack([first, p], axis=-1)


def ellipse_section_state(scene, s, p, energy=0.5, arm_angle=0.0, spin=0.0) -> jax.Array:
    """The state ``(..., 6)`` just after end P1 hits the wall at arc length ``s`` with ``p`` (the Birkhoff section).

    Args:
        scene: a ``StickInEllipse``.
        s: arc length of the contact (length), any shape; ``p``: the
            tangential momentum ``sqrt(M) v_t / sqrt(2 E)`` in ``[-1, 1]``, same shape.
        energy: the energy ``E > 0``.
        arm_angle: angle (radians) from the wall's outward normal at the
            contact to the stick ``u`` (pointing from the centre to P1),
            anticlockwise; 0 puts the stick along the normal. Ignored for a point.
        spin: ``omega`` (radians per time; 0 for a stick that never turns).

    Returns:
        ``(..., 6)``; NaN where no such state exists: ``|p| > 1``, the spin
        takes more than the energy left, P2 would be outside the table, or
        P1 would not be leaving the wall.
    """
    s, p = jnp.broadcast_arrays(jnp.asarray(s, jnp.float64), jnp.asarray(p, jnp.float64))
    t = parameter_angle(scene, s)
    point = jnp.stack([scene.a * jnp.cos(t), scene.b * jnp.sin(t)], axis=-1)
    speed = _speed_along(scene, t)[..., None]
    tangent = jnp.stack([-scene.a * jnp.sin(t), scene.b * jnp.cos(t)], axis=-1) / speed
    outward = jnp.stack([tangent[..., 1], -tangent[..., 0]], axis=-1)
    u = jnp.cos(arm_angle) * outward + jnp.sin(arm_angle) * tangent
    centre = point - scene.ell * u
    alpha = jnp.arctan2(u[..., 1], u[..., 0]) if scene.kind != "point" else jnp.zeros_like(t)
    omega = jnp.zeros_like(t) + (0.0 if scene.kind != "rotor" else spin)
    v_scale = jnp.sqrt(2.0 * energy / scene.mass)
    v_t = p * v_scale
    rotation = scene.inertia * omega**2 / scene.mass if scene.kind == "rotor" else jnp.zeros_like(t)
    normal_squared = v_scale**2 - v_t**2 - rotation
    v_n = jnp.sqrt(jnp.where(normal_squared >= 0.0, normal_squared, jnp.nan))
    v = v_t[..., None] * tangent - v_n[..., None] * outward
    state = jnp.concatenate([centre, alpha[..., None], v, omega[..., None]], axis=-1)
    # P1 must be leaving the wall: its velocity along the outward normal is negative.
    ends_velocity = v + (scene.ell * omega)[..., None] * jnp.stack([-u[..., 1], u[..., 0]], axis=-1)
    leaving = jnp.sum(ends_velocity * outward, axis=-1) < 0.0
    other_inside = scene.gaps(state)[..., 1] >= 0.0
    return jnp.where((leaving & other_inside)[..., None], state, jnp.nan)


def ellipse_section_seeds(scene, count: int, energy=0.5, arm_angle=0.0, spin=0.0):
    """``count`` states spread evenly (Halton) over the Birkhoff section ``[0, L) x (-1, 1)``; some NaN for a stick."""
    index = np.arange(1, count + 1)
    s = halton(index, 2) * float(ellipse_length(scene))
    p = 2.0 * halton(index, 3) - 1.0
    return ellipse_section_state(scene, s, p, energy, arm_angle, spin)


# -- the explorer's chart of the Birkhoff section (StickInEllipse.section_chart) ----------


def _start(scene, s, p, invariants):
    states = ellipse_section_state(scene, s, p, invariants["energy"], invariants.get("arm_angle", 0.0))
    return states, jnp.ones(jnp.shape(states)[:-1], jnp.int32)


def _seeds(scene, count, invariants):
    states = ellipse_section_seeds(scene, count, invariants["energy"], invariants.get("arm_angle", 0.0))
    return states, jnp.ones((count,), jnp.int32)


def _edge(scene, s, invariants):
    del invariants  # every p in [-1, 1] is reached with the spin at rest
    ones = np.ones_like(np.asarray(s, dtype=np.float64))
    return np.stack([-ones, ones], axis=-1)


def _points(scene, states, contacts):
    return ellipse_section(scene, states, contacts, "birkhoff")


def draw_ellipse_orbit(ax, scene, state0, orb, color, *, stick_every: int = 1):
    """The table, the centre's path from ``state0`` through ``orb``'s collisions and the stick at each one."""
    turn = np.linspace(0.0, 2.0 * np.pi, 400)
    a, b = float(scene.a), float(scene.b)
    ax.plot(a * np.cos(turn), b * np.sin(turn), color="k", lw=1.2)
    states = np.asarray(orb.state)
    path = np.concatenate([np.asarray(state0)[None, :2], states[:, :2]])
    ax.plot(path[:, 0], path[:, 1], color=color, lw=0.8, alpha=0.9)
    if float(scene.ell) > 0:
        ends = np.asarray(end_points(scene, states))  # (n, 2, 2)
        for stick in ends[::stick_every]:
            ax.plot(stick[:, 0], stick[:, 1], color="0.3", lw=0.9, alpha=0.55)
    ax.plot(*path[0], "o", color=color, ms=5)
    ax.set_xlim(-1.05 * a, 1.05 * a)
    ax.set_ylim(-1.05 * b, 1.05 * b)
    ax.set_aspect("equal")
    ax.set_xlabel("x (length)")
    ax.set_ylabel("y (length)")


# The axes of each section, for pictures (StickInEllipse.section_axis_labels).
SECTION_AXIS_LABELS = {
    "birkhoff": (r"$s$: arc length of the contact from $(a, 0)$ (length)", r"$p = \sqrt{M}\,v_t/\sqrt{2E}$"),
    "angle": (r"$t$: parameter angle of the contact, $(a \cos t, b \sin t)$ (rad)", r"$p = \sqrt{M}\,v_t/\sqrt{2E}$"),
}

ELLIPSE_CHART = SectionChart(
    title="Birkhoff section of the touching end",
    axis_labels=SECTION_AXIS_LABELS["birkhoff"],
    invariant_symbols={"energy": "E"},
    default_invariants=lambda scene: {"energy": 0.5},
    x_range=lambda scene: (0.0, float(ellipse_length(scene))),
    edge=_edge,
    start=_start,
    seeds=_seeds,
    points=_points,
    draw_configuration=draw_ellipse_orbit,
)
