"""What the two stick-between-walls scenes share: parameters, the contact search, contacts.

Walls are the planes ``z = 0`` (the floor) and ``z = h`` (the ceiling). In
both scenes the height of end ``k`` (``e_k = +1`` for P1, ``-1`` for P2) is a
line plus a sinusoid,

    z_k(t) = z0 + vz t + e_k ell a(t),   a(t) = A cos(W t) + D sin(W t) / W,

where ``a`` is the vertical component of the stick's unit vector, turning at
the angular speed ``W`` (``a(0) = A``, ``a'(0) = D``). The four contact gaps,
in units of length and ``>= 0`` inside, are ``[z_1, z_2, h - z_1, h - z_2]``:
P1 and P2 on the floor, then on the ceiling. Since ``|a''| = W^2 |a| <= W^2
amp`` with ``amp = sqrt(A^2 + (D/W)^2) <= 1``, every gap has ``|g''| <= ell W^2
amp``, the bound the safe-step first root search (``jaxbill._engine.first_root``)
needs; and no end can touch a wall while the centre is more than ``ell amp``
from both walls, so the search jumps over that stretch of the flight.
"""

from __future__ import annotations

import abc
import math
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbill._engine.first_root import RootBounds, first_smallest, select
from jaxbill._engine.step import cos_sin, rarely, where
from jaxbill._engine.validation import (
    broadcast_parameters,
    check_parameter,
    is_concrete,
    on_wall_not_inwards,
    real_parameter,
)
from jaxbill._engine.validation import motion_is_representable as representable
from jaxbill._scenes.protocols import NO_CONTACT, SEVERAL_CONTACTS, WALL_TOLERANCE

FLOOR = 1  # contact code of end P1 on the floor (P2: -1)
CEILING = 3  # contact code of end P1 on the ceiling (P2: -3)

GAP_NAMES = ("end P1 (floor)", "end P2 (floor)", "end P1 (ceiling)", "end P2 (ceiling)")
END_SIGNS = (1.0, -1.0, 1.0, -1.0)  # e_k of each gap
_CONTACT_CODES = (FLOOR, -FLOOR, CEILING, -CEILING)
# Every contact code of a wall scene's collisions: none (0), P1/P2 on the floor (1, -1) or
# the ceiling (3, -3), both ends at once (2).
CONTACT_CODES = (-CEILING, -FLOOR, NO_CONTACT, FLOOR, SEVERAL_CONTACTS, CEILING)

# Two gaps within this many ulps of h at one contact touch at the same instant
# (the stick landing flat: a kink of the (theta, z) billiard's wall).
_CORNER_ULPS = 64.0

# Orbits per vectorised lane of a batch on a CPU: a turning stick's orbits one after
# another (its search branches, and a lane would wait for its slowest orbit), the static
# one's closed form in 256 (``benchmarks/bench_drivers.py`` measures the widths).
_BATCH_CHUNK = {"rotor": 1, "static": 256}


def checked_parameters(h, ell, mass, inertia):
    """Validate concrete parameters; return them broadcast to one shape, and the kind."""
    h, ell, mass = (real_parameter(name, v) for name, v in (("h", h), ("ell", ell), ("mass", mass)))
    if inertia is not None:
        inertia = real_parameter("inertia", inertia)
    broadcast_parameters(h=h, ell=ell, mass=mass, inertia=inertia)
    for name, v in (("h", h), ("ell", ell), ("mass", mass)):
        check_parameter(name, v, np.isfinite(v), "finite")
    check_parameter("h", h, h > 0, "> 0 (the distance between the walls)")
    check_parameter("ell", ell, ell > 0, "> 0 (the stick's half-length)")
    check_parameter("mass", mass, mass > 0, "> 0")
    if inertia is None:
        inertia = mass * ell**2
    else:
        check_parameter("inertia", inertia, ~np.isnan(inertia), "a number or inf, not NaN")
        check_parameter("inertia", inertia, inertia > 0, "> 0 (or inf for a stick that never turns)")
    static = bool(np.all(np.isinf(inertia)))
    if not static and np.any(np.isinf(inertia)):
        raise ValueError("inertia must be all finite or all inf within one batch of scenes")
    return (*np.broadcast_arrays(h, ell, mass, inertia), "static" if static else "rotor")


def scene_leaves(h, ell, mass, inertia):
    """``(h, ell, mass, inertia, kind)`` for a wall scene's constructor, the leaves as float64 arrays.

    Concrete parameters are checked here; traced ones (a scene built inside
    ``jit``) cannot be, and invalid values poison the results with NaN instead.
    """
    leaves = [h, ell, mass] + ([] if inertia is None else [inertia])
    if all(is_concrete(v) for v in leaves):
        h, ell, mass, inertia, kind = checked_parameters(h, ell, mass, inertia)
    else:
        inertia = mass * ell**2 if inertia is None else inertia
        kind = "static" if isinstance(inertia, float) and math.isinf(inertia) else "rotor"
    return (*(jnp.asarray(v, dtype=jnp.float64) for v in (h, ell, mass, inertia)), kind)


def check_scene(scene) -> None:
    """ValueError if a wall scene's (possibly replaced) parameters are invalid or change its ``kind``."""
    *_, kind = checked_parameters(scene.h, scene.ell, scene.mass, scene.inertia)
    if kind != scene.kind:
        raise ValueError(f"the parameters describe a {kind!r} scene, not {scene.kind!r}: build a new scene")


def check_batch_of_states(scene, state: np.ndarray) -> None:
    """ValueError unless a batch of scenes comes with a batch of states of the same size."""
    h = np.asarray(scene.h)
    if h.ndim and state.ndim == 2 and h.shape[0] != state.shape[0]:
        raise ValueError(f"a batch of {h.shape[0]} scenes needs a batch of {h.shape[0]} states; got {state.shape[0]}")


def parameters_are_valid(h, ell, mass, inertia, kind: str) -> jax.Array:
    ok = (h > 0) & (ell > 0) & (mass > 0) & jnp.isfinite(h) & jnp.isfinite(ell) & jnp.isfinite(mass)
    if kind == "rotor":
        ok &= (inertia > 0) & jnp.isfinite(inertia)
    return ok


def batch_chunk(kind: str) -> int:
    return _BATCH_CHUNK[kind]


# -- the vertical profile of the ends ------------------------------------------


def turn(spin2: jax.Array, t: jax.Array):
    """``cos(W t)`` and ``sin(W t) / W`` from ``W^2``, smooth through ``W = 0``."""
    turning = spin2 > 0.0
    spin = jnp.sqrt(jnp.where(turning, spin2, 1.0))
    cos_spin, sin_spin = cos_sin(spin * t)
    cos = jnp.where(turning, cos_spin, 1.0)
    # 1/W is the same at every root step of a flight: a product, not a division, at each.
    sinc = jnp.where(turning, sin_spin * (1.0 / spin), t)
    return cos, sinc


def gaps_along_flight(profile, t):
    """The four gaps and their time derivatives after a flight of ``t`` (4-tuples).

    ``profile = (z0, vz, A, D, W^2, ell, h)``; see the module docstring.
    """
    z0, vz, along, turn_rate, spin2, ell, h = profile
    cos, sinc = turn(spin2, t)
    reach = ell * (along * cos + turn_rate * sinc)
    reach_slope = ell * (turn_rate * cos - along * spin2 * sinc)
    z = z0 + vz * t
    return end_gaps(z, reach, h), end_gaps_closing(vz, reach_slope, -1.0)


def end_gaps(z, reach, h) -> tuple:
    """``(z1, z2, h - z1, h - z2)`` for end heights ``z1, z2 = z +- reach``."""
    return z + reach, z - reach, h - (z + reach), h - (z - reach)


def end_gaps_closing(rise, reach_rise, sign) -> tuple:
    """The rates of the four gaps for end rises ``rise +- reach_rise``, times ``-sign``.

    ``sign = -1``: the gaps' time derivatives; ``sign = +1``: the rates at which
    they close (the approach speeds).
    """
    return (
        -sign * (rise + reach_rise),
        -sign * (rise - reach_rise),
        sign * (rise + reach_rise),
        sign * (rise - reach_rise),
    )


def _band_crossing(z0, vz, low, high):
    """Interval ``(t_in, t_out)`` of ``t >= 0`` with ``low < z0 + vz t < high`` (empty if none)."""
    safe_vz = jnp.where(vz == 0.0, 1.0, vz)
    t_low, t_high = (low - z0) / safe_vz, (high - z0) / safe_vz
    t_in = jnp.maximum(jnp.minimum(t_low, t_high), 0.0)
    t_out = jnp.maximum(t_low, t_high)
    inside_now = (z0 > low) & (z0 < high)
    t_in = jnp.where(vz == 0.0, jnp.where(inside_now, 0.0, jnp.inf), t_in)
    t_out = jnp.where(vz == 0.0, jnp.where(inside_now, jnp.inf, -jnp.inf), t_out)
    no_band = low >= high  # a stick too long to turn over
    return jnp.where(no_band, jnp.inf, t_in), jnp.where(no_band, -jnp.inf, t_out)


def search_bounds(profile) -> RootBounds:
    """The safe-step search's bounds for the flight with this vertical profile."""
    z0, vz, along, turn_rate, spin2, ell, h = profile
    eps = jnp.finfo(jnp.float64).eps
    # amp bounds |a(t)| for all t (<= 1 for a unit vector), padded for rounding.
    spin2_safe = jnp.where(spin2 > 0.0, spin2, 1.0)
    amp = jnp.sqrt(along * along + jnp.where(spin2 > 0.0, turn_rate * turn_rate / spin2_safe, 0.0))
    amp = jnp.minimum(amp * (1.0 + 8.0 * eps), 1.0)
    reach = ell * amp
    curvature = reach * spin2
    quiet_in, quiet_out = _band_crossing(z0, vz, reach, h - reach)
    time_scale = 1.0 / (jnp.abs(vz) / h + jnp.sqrt(spin2))
    return RootBounds(curvature, curvature, quiet_in, quiet_out, time_scale)


def straight_contact_time(gaps: tuple, closing_speeds: tuple):
    """First contact when every gap is linear in time: ``(t, gap index)``."""
    times = []
    for gap, speed in zip(gaps, closing_speeds, strict=True):
        closing = speed > 0.0
        times.append(jnp.where(closing, jnp.maximum(gap, 0.0) / jnp.where(closing, speed, 1.0), jnp.inf))
    index = first_smallest(tuple(times))
    return select(tuple(times), index), index


# -- contacts -------------------------------------------------------------------


def resolve_contact(scene, state: tuple, index: jax.Array):
    """Apply the impulse of gap ``index``; a simultaneous contact of the other end too.

    ``scene`` provides, on components, ``end_gaps_and_speeds`` and
    ``kick(state, gap)``. At most one gap per end can vanish (``h > 0``),
    so a second contact is the other end on either wall: the faster-approaching
    of the two is kicked first, the other after it if it still approaches (as
    for a lens corner).
    """
    gaps, speeds = scene.end_gaps_and_speeds(state)
    other_end = jnp.where((index == 0) | (index == 2), 1, 0)
    # The other end's nearer wall.
    other = jnp.where(select(gaps, other_end) <= select(gaps, other_end + 2), other_end, other_end + 2)
    gap_other, speed_other = select(gaps, other), select(speeds, other)
    several = (gap_other <= _CORNER_ULPS * jnp.finfo(jnp.float64).eps * scene.h) & (speed_other > 0.0)

    def one_end(state):
        return scene.kick(state, index), select(tuple(jnp.int32(c) for c in _CONTACT_CODES), index)

    def both_ends(state):
        first = jnp.where(speed_other > select(speeds, index), other, index)
        second = jnp.where(first == index, other, index)
        kicked = scene.kick(state, first)
        still_approaching = select(scene.end_approach_speeds(kicked), second) > 0.0
        kicked = where(still_approaching, scene.kick(kicked, second), kicked)
        return kicked, jnp.int32(SEVERAL_CONTACTS) + jnp.zeros_like(index)

    # A second contact is rare: one orbit skips its impulse (see ``rarely``).
    return rarely(several, both_ends, one_end, state)


def end_sign(gap: jax.Array) -> jax.Array:
    """``e_k`` of gap ``gap`` (0..3): +1 for end P1, -1 for end P2."""
    return jnp.where((gap == 0) | (gap == 2), 1.0, -1.0)


class WallsEngine(eqx.Module):
    """The engine's questions (``jaxbill._engine.step``), the same for the stick between walls in 2D and 3D.

    An abstract module: the scene answers ``body_turns``, ``vertical_profile``,
    ``end_gaps``, ``end_approach_speeds`` and ``moved(state, t)`` (the free
    flight to ``t``, renormalised where the state has constraints) on
    components, and ``kick``; it may answer ``end_gaps_and_speeds`` at once.
    """

    contact_codes: ClassVar[tuple[int, ...]] = CONTACT_CODES

    @property
    @abc.abstractmethod
    def body_turns(self) -> bool:
        """Static: the stick turns (finite inertia)."""

    @abc.abstractmethod
    def vertical_profile(self, state: tuple):
        """The flight's end heights as sinusoids in time (``search_bounds`` reads their bounds)."""

    @abc.abstractmethod
    def end_gaps(self, state: tuple) -> tuple:
        """The four gaps of the components (each end to each wall)."""

    @abc.abstractmethod
    def end_approach_speeds(self, state: tuple) -> tuple:
        """The four gaps' rates of closing."""

    @abc.abstractmethod
    def moved(self, state: tuple, t) -> tuple:
        """The free flight of the components to time ``t``."""

    @property
    def searches_for_roots(self) -> bool:
        """A turning stick's end heights are sinusoids; a static one's are lines (closed form)."""
        return self.body_turns

    def root_search(self, state: tuple):
        """``(vertical profile, RootBounds)`` of the flight from ``state``."""
        profile = self.vertical_profile(state)
        return profile, search_bounds(profile)

    def gaps_along_flight(self, profile, t: jax.Array):
        """The four gaps and their time derivatives after a flight of ``t`` (4-tuples)."""
        return gaps_along_flight(profile, t)

    def closed_form_contact(self, state: tuple, constants: None = None):
        """``(t, index)`` for a stick that never turns: every gap is linear in time."""
        return straight_contact_time(*self.end_gaps_and_speeds(state))

    def end_gaps_and_speeds(self, state: tuple) -> tuple:
        """``(end_gaps, end_approach_speeds)`` of the components; a scene whose two share work computes them
        together (2D: one cosine and sine of ``theta``, where each took its own)."""
        return self.end_gaps(state), self.end_approach_speeds(state)

    def collide_at(self, state: tuple, t: jax.Array, index: jax.Array, constants: None = None):
        """The flight to ``t`` and the impulse(s) of gap ``index`` (see ``resolve_contact``)."""
        return resolve_contact(self, self.moved(state, t), index)


def state_is_inside(scene, state) -> jax.Array:
    """No end through a wall by more than the tolerance, none on a wall and not moving away from it."""
    gaps = scene.gaps(state)
    inside = jnp.all(gaps >= -WALL_TOLERANCE * scene.h)
    return inside & ~on_wall_not_inwards(gaps, scene.approach_speeds(state))


def motion_is_representable(scene, v, w2, state) -> jax.Array:
    """Traceable: velocities whose squares float64 represents (see ``jaxbill._engine.validation``)."""
    return representable(v, w2, scene.energy(state), jnp.maximum(scene.h, scene.ell))
