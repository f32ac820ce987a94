"""One collision of any scene, built from the scene's own pieces: the reference every driver runs.

A scene answers four questions about one orbit (all pure, traceable functions
of one orbit's values; see ``jaxbill._engine.interface.Scene``). A state is passed to them
as its *components*, a tuple of ``S`` scalars (or of equal-shaped arrays, one
element per orbit), and they return tuples: no slicing, stacking, gathering or
reduction over a state or over the gaps, so that the same functions run under
``vmap`` in XLA and, a block of orbits at a time, inside a Pallas (Triton)
kernel, which lowers none of those.

* ``scene.root_search(state) -> (profile, RootBounds)``: for a scene whose gaps
  are transcendental in time (a turning stick), what its gaps depend on along
  the flight from ``state`` and the bounds the safe-step search needs;
* ``scene.gaps_along_flight(profile, t) -> (gaps, slopes)``: the K gaps and
  their time derivatives after a flight of ``t``, as two K-tuples; or
  ``(gaps, slopes, curvatures)``, with the second derivatives too, for a scene
  whose ``RootBounds`` bound the third (sharper steps, see
  ``jaxbill._engine.first_root``);
* ``scene.closed_form_contact(state, constants) -> (t, index)``: for a scene
  whose gaps are polynomials in time (a static body, a point), the contact
  time directly;
* ``scene.collide_at(state, t, index, constants) -> (state, contact)``: the
  flight to ``t`` and the impulse(s) of the contact in gap ``index``.

``scene.searches_for_roots`` (static) says which of the two contact-time paths
the scene takes, so a scene compiles only what it needs.

Two ways to run these pieces share them unchanged:

* ``advance``: one whole collision (the search as a ``while_loop``), with the
  contact time differentiated implicitly. ``jb.collide``, single orbits and the
  tangent maps use it.
* the lane state machine: ``search_step`` takes one root step of a lane's
  search, and ``end_and_begin`` ends a lane's flight whose contact was found
  (the impulse) and begins the next (``begin_flight``). A batch of orbits
  advances in one loop of these two moves in which no orbit waits for
  another. The XLA driver (``jaxbill._engine.lanes``) and the Pallas kernel
  (``jaxbill._engine.pallas``) run it.
"""

from __future__ import annotations

import contextlib
import contextvars
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxbill._engine.first_root import REFUSED, first_root, root_step, search_start, select, with_curvatures
from jaxbill._engine.interface import NO_CONTACT
from jaxbill._engine.results import Result, collision_status
from jaxbill._engine.trig import EXACT_REMAINDER_LIMIT, TWO_PI, cos_sin_polynomial, remainder_two_pi
from jaxbill._engine.validation import is_concrete

# Static bound on root-search steps per collision. Typical collisions take a
# handful; a grazing departure can take a few hundred.
MAX_ROOT_STEPS = 4096


def components(state: jax.Array) -> tuple:
    """The tuple of a state's ``S`` components: ``state[..., i]`` for each ``i``."""
    return tuple(state[..., i] for i in range(state.shape[-1]))


def orbit_constants(scene, state0: jax.Array) -> Any:
    """What ``scene`` holds fixed along the orbit from ``state0`` ``(S,)``: ``advance``'s ``constants``."""
    return scene.orbit_constants(components(state0))


def stacked(parts: tuple) -> jax.Array:
    """A state ``(..., S)`` from its components (the inverse of ``components``)."""
    return jnp.stack(parts, axis=-1)


_CONDITIONALS = contextvars.ContextVar("jaxbill_conditionals", default=True)


# Inside a Pallas kernel: ``rarely`` branches on whether any lane of the block needs its rare side.
_RARE_BY_BLOCK = contextvars.ContextVar("jaxbill_rare_by_block", default=False)


@contextlib.contextmanager
def without_conditionals(rare_by_block: bool = False):
    """Trace scene code in which ``cos_sin`` and ``rarely`` add no ``lax.cond``: the lane drivers.

    A Pallas kernel is one fusion already, and Triton lowers no conditional over
    a block of lanes; the XLA lane state machine measured slower with them
    (the walls' search most; ``benchmarks/bench_drivers.py`` times the drivers), so only ``advance`` (single
    orbits, lockstep batches, tangents) keeps them. ``rare_by_block``: inside a
    kernel, ``rarely`` computes its rare side only when some lane of the block
    needs it (one branch on a scalar, which Triton lowers).
    """
    token = _CONDITIONALS.set(False)
    block_token = _RARE_BY_BLOCK.set(rare_by_block)
    try:
        yield
    finally:
        _RARE_BY_BLOCK.reset(block_token)
        _CONDITIONALS.reset(token)


def _conditionals() -> bool:
    return _CONDITIONALS.get() and jax.default_backend() == "cpu"


def cos_sin(phi):
    """``(cos phi, sin phi)``, computed once however many values use them (see ``computed_once``).

    XLA:CPU copies an elementwise producer into every fusion that consumes it,
    and a root step's gaps and slopes are four fusions: ``cos`` and ``sin``
    were evaluated four times per step, the larger part of a batch's root step
    (a batch of spinning sticks, ``benchmarks/bench_drivers.py``).
    Both come from one polynomial evaluation that vectorises
    (``jaxbill._engine.trig``), where XLA:CPU calls ``cos`` and ``sin`` value by value.
    """
    return computed_once(cos_sin_polynomial, phi)


def wrapped_angle(phi):
    """``phi`` wrapped into ``[-pi, pi)``: ``jnp.remainder(phi + pi, 2 pi) - pi``, to the bit.

    In a lockstep batch (``vmapped_over_lanes``) by ``trig.remainder_two_pi``'s
    exact arithmetic, which vectorises, where XLA:CPU calls ``fmod`` value by
    value (a large share of the circle billiard's short collision), and ``jnp.remainder``
    itself past ``2**26`` turns (``rarely``). Elsewhere ``jnp.remainder``: one
    orbit is bound by the chain of dependent operations, which the library's
    ``fmod`` keeps shorter (the circle's orbit ran slower without it),
    and the lane drivers would compute both sides of a ``rarely``.
    """
    shifted = phi + jnp.pi
    if _LANE_AXIS.get() is None or not _conditionals():
        return jnp.remainder(shifted, TWO_PI) - jnp.pi
    beyond = jnp.abs(shifted) >= EXACT_REMAINDER_LIMIT
    return rarely(beyond, lambda a: jnp.remainder(a, TWO_PI), remainder_two_pi, shifted) - jnp.pi


def computed_once(function, *operands):
    """``function(*operands)``, evaluated once however many later values use it.

    XLA:CPU copies an elementwise producer into every fusion that consumes it
    (an ``optimization_barrier`` does not stop it). A conditional is a boundary
    no fusion crosses, so ``function`` runs inside one whose predicate is
    always true; the predicate passes through an ``optimization_barrier``: a
    constant one would be folded and the conditional removed. Only XLA:CPU gets
    it; see ``without_conditionals`` for the drivers that do without.
    """
    if not _conditionals() or all(is_concrete(x) for x in jax.tree.leaves(operands)):
        # Called eagerly (e.g. ``jb.end_points`` on concrete states) nothing is fused, and a conditional
        # would compile a new program at every call (its branches are new functions each time).
        return function(*operands)
    always = jax.lax.optimization_barrier(jnp.asarray(True))
    never_taken = lambda *ops: jax.tree.map(lambda r: jnp.zeros(r.shape, r.dtype), jax.eval_shape(function, *ops))  # noqa: E731
    return jax.lax.cond(always, function, never_taken, *operands)


_LANE_AXIS: contextvars.ContextVar[str | None] = contextvars.ContextVar("jaxbill_lane_axis", default=None)

LANE_AXIS = "jaxbill_lanes"


def vmapped_over_lanes(function, in_axes):
    """``jax.vmap(function, in_axes)`` over a lane of orbits, in which ``rarely`` skips its rare case in every
    lane when no lane needs it (the lockstep drivers)."""
    batched = jax.vmap(function, in_axes=in_axes, axis_name=LANE_AXIS)

    def run(*args):
        token = _LANE_AXIS.set(LANE_AXIS)
        try:
            return batched(*args)
        finally:
            _LANE_AXIS.reset(token)

    return run


def rarely(condition, if_true, if_false, *operands):
    """``if_true(*operands)`` where ``condition`` holds, else ``if_false(*operands)``: the rare case skipped.

    One orbit on XLA:CPU takes a branch, so the rare case (a corner: a second
    end on the wall at the same instant) costs nothing where it does not
    happen, which a static lens's short collisions notice. Under ``vmap``
    a branch becomes a select and both sides are computed; inside
    ``vmapped_over_lanes`` the lanes first ask whether any of them needs the
    rare side, and compute it only then, where a select would pay for it in every lane.
    The XLA lane driver (``without_conditionals``) selects; the Pallas kernel
    (``rare_by_block``) computes the rare side only in blocks of lanes where
    some lane needs it (measured on a GPU: the performance page, "On a GPU").
    The values are the same every way. ``benchmarks/HISTORY.md`` has each
    change's measurements.
    """

    def select_per_lane(*ops):
        return jax.tree.map(lambda a, b: jnp.where(condition, a, b), if_true(*ops), if_false(*ops))

    if not _conditionals():
        if _RARE_BY_BLOCK.get():
            # A max over int32: Triton lowers no reduction of booleans (jnp.any).
            some_lane = jnp.max(jnp.asarray(condition, jnp.int32)) > 0
            return jax.lax.cond(some_lane, select_per_lane, if_false, *operands)
        return select_per_lane(*operands)
    axis = _LANE_AXIS.get()
    if axis is not None:
        some_lane = jax.lax.psum(jnp.asarray(condition, jnp.int32), axis) > 0
        return jax.lax.cond(some_lane, select_per_lane, if_false, *operands)
    return jax.lax.cond(condition, if_true, if_false, *operands)


def where(condition, if_true: tuple, if_false: tuple) -> tuple:
    """``jnp.where`` component by component."""
    return tuple(jnp.where(condition, a, b) for a, b in zip(if_true, if_false, strict=True))


class Collision(NamedTuple):
    """One collision of an orbit (or of a block of orbits, elementwise).

    Attributes:
        state: the state just after it, as components (a driver that keeps
            states as arrays stacks them).
        dt: the flight time to it (``inf``: the flight never ends; NaN: no
            contact was proven).
        contact: the scene's contact code (0: none).
        status: int32, its ``jaxbill._engine.results.Result``: ``FINISHED``
            where it went well, else what went wrong.
    """

    state: Any
    dt: jax.Array
    contact: jax.Array
    status: jax.Array


def checks_its_bounds(scene) -> bool:
    """Static: ``scene`` checks the bounds of its root search and refuses a step that breaks them
    (``jaxbill._engine.first_root.REFUSED``; a scene says so by ``checks_curvature = True``)."""
    return bool(getattr(scene, "checks_curvature", False))


def escape_code(scene) -> int | None:
    """Static: the contact code of a collision through a hole in ``scene``'s boundary (``None``: it has none)."""
    return getattr(scene, "escape_code", None)


def stop_condition(scene):
    """Static: ``scene``'s condition on a state's components just after a collision that ends its orbit
    (``Result.STOPPED``), or ``None``."""
    return getattr(scene, "stop_condition", None)


def stops_orbits(scene) -> bool:
    """Static: an orbit of ``scene`` can end for good (``jaxbill._engine.results.STOPPING``), so the
    drivers hold it from then on and read its result collision by collision."""
    return escape_code(scene) is not None or stop_condition(scene) is not None


def finish_step(
    state: tuple, moved_and_kicked: tuple, t, contact, ok, refused=None, escape=None, stop=None
) -> Collision:
    """A collision's result: unchanged for a flight that never ends, NaN for a failed search.

    ``ok``: the search ended within its step bound; ``refused``: the scene
    refused a step of it (``None``: a scene that never does). ``escape``: the
    contact code of an exit through a hole (``None``: the scene has none);
    ``stop``: whether the scene's stopping condition holds after the
    collision (``None``: it has none). Either ends the orbit
    (``Result.ESCAPED``, ``Result.STOPPED``) where the collision was reached.
    """
    reached = jnp.isfinite(t)
    status = collision_status(t, ok, refused)
    ok = ok & ~jnp.isnan(t)  # a search that met a NaN gap proved nothing
    new_state = where(reached, moved_and_kicked, state)
    contact = jnp.where(reached, contact, jnp.int32(NO_CONTACT))
    new_state = tuple(jnp.where(ok, a, jnp.nan) for a in new_state)
    contact = jnp.where(ok, contact, jnp.int32(NO_CONTACT))
    ended = reached & ok & (status == Result.FINISHED)
    escaped = jnp.zeros(jnp.shape(t), bool)
    if escape is not None:
        escaped = ended & (contact == escape)
        status = jnp.where(escaped, jnp.int32(Result.ESCAPED), status)
    if stop is not None:
        status = jnp.where(ended & ~escaped & stop, jnp.int32(Result.STOPPED), status)
    return Collision(new_state, jnp.where(ok, t, jnp.nan), contact, status)


def finish_scene_step(scene, state: tuple, moved_and_kicked: tuple, t, contact, ok, refused=None) -> Collision:
    """``finish_step`` with ``scene``'s ways to end an orbit: its holes and its stopping condition."""
    condition = stop_condition(scene)
    stop = None if condition is None else jnp.asarray(condition(moved_and_kicked), bool)
    return finish_step(state, moved_and_kicked, t, contact, ok, refused, escape_code(scene), stop)


def refused_search(scene, index):
    """Whether a search of ``scene`` that ended at gap ``index`` was refused (``None``: it never is)."""
    return index == REFUSED if checks_its_bounds(scene) else None


# -- one whole collision ------------------------------------------------------------


@jax.custom_jvp
def searched_contact_time(scene, state: tuple):
    """First contact of a turning body: ``(t, gap index, ok)`` (``t = inf``: never; ``ok``: within the step bound;
    the index ``REFUSED`` where the scene refused the search)."""
    profile, bounds = scene.root_search(state)
    gaps = lambda t: scene.gaps_along_flight(profile, t)  # noqa: E731
    t, index, _, ok = first_root(gaps, bounds, MAX_ROOT_STEPS, checks_its_bounds(scene))
    return t, index, ok


# the integer outputs' tangents are float0 zeros, which jax's annotation of defjvp leaves out
@searched_contact_time.defjvp  # pyright: ignore[reportArgumentType]
def _searched_contact_time_jvp(primals, tangents):
    # Implicit differentiation of g_k(t*; scene, state) = 0: the derivative of
    # the root comes from the gap at the root, never from the search iterations.
    scene, state = primals
    t, index, ok = searched_contact_time(scene, state)
    finite = jnp.isfinite(t)
    t_safe = jnp.where(finite, t, 0.0)

    def gap_at_root(scene_, state_):
        profile, _ = scene_.root_search(state_)
        return select(scene_.gaps_along_flight(profile, t_safe)[0], index)

    _, gap_tangent = jax.jvp(gap_at_root, primals, tangents)
    profile, _ = scene.root_search(state)
    slope = select(scene.gaps_along_flight(profile, t_safe)[1], index)
    t_tangent = jnp.where(finite & (slope != 0.0), -gap_tangent / slope, 0.0)
    zero = np.zeros((), dtype=jax.dtypes.float0)
    return (t, index, ok), (t_tangent, zero, zero)


def advance(scene, state: jax.Array, constants: Any):
    """``(new_state, dt, contact)``: the flight from ``state`` ``(S,)`` to the next collision and its impulse.

    For a state known to be valid; ``constants`` are ``scene.orbit_constants``
    of the orbit's first state (its components).
    """
    collision = advance_components(scene, components(state), constants)
    return stacked(collision.state), collision.dt, collision.contact


def advance_components(scene, parts: tuple, constants: Any) -> Collision:
    """``advance`` on a state's components, in and out, with the collision's status: a loop that carries
    them never packs a state into an array and slices it again at every collision (the closed forms'
    single orbits, whose collisions are short, gain most)."""
    refused = None
    if scene.searches_for_roots:
        t, index, ok = searched_contact_time(scene, parts)
        refused = refused_search(scene, index)
    else:
        # Each part computed once (see ``computed_once``), not in every fusion that consumes it: a
        # lockstep batch of lenses, whose collisions are short, paid for each part several times.
        t, index = computed_once(lambda p, c: scene.closed_form_contact(p, c), parts, constants)
        ok = jnp.array(True)
    t_reached = jnp.where(jnp.isfinite(t), t, 0.0)
    kicked, contact = computed_once(lambda *args: scene.collide_at(*args), parts, t_reached, index, constants)
    return finish_scene_step(scene, parts, kicked, t, contact, ok, refused)


# -- the lane state machine ---------------------------------------------------------


class Lane(NamedTuple):
    """One orbit in flight, between two root steps.

    Attributes:
        state: the components of the state at the start of the flight (just
            after the last collision).
        t: ``()`` the search's current time along the flight (for a
            closed-form scene, the contact time).
        index: ``()`` int32, the gap the search approaches (or found).
        found: ``()`` the search is over: a proven root at ``t``, ``t = inf``
            (no contact ever) or a hopeless (non-finite) lane.
        steps: ``()`` int32, root steps taken in this flight.
        profile: the scene's ``root_search`` profile (``None`` for a closed form).
        bounds: the flight's ``RootBounds`` (``None`` for a closed form).
    """

    state: tuple
    t: jax.Array
    index: jax.Array
    found: jax.Array
    steps: jax.Array
    profile: Any
    bounds: Any


def begin_flight(scene, state: tuple, constants: Any) -> Lane:
    """A lane about to search for the contact that ends the flight from ``state`` (components)."""
    if scene.searches_for_roots:
        profile, bounds = scene.root_search(state)
        t = search_start(bounds)
        none = jnp.zeros(jnp.shape(t), jnp.int32)
        return Lane(state, t, none, jnp.isinf(t), none, profile, bounds)
    t, index = scene.closed_form_contact(state, constants)
    # Shapes from t, not scalar literals: inside a kernel every lane field is a block.
    return Lane(
        state,
        t,
        index.astype(jnp.int32),
        jnp.isfinite(t) | jnp.isnan(t) | jnp.isinf(t),
        jnp.zeros(jnp.shape(t), jnp.int32),
        None,
        None,
    )


def search_step(scene, lane: Lane) -> Lane:
    """One safe step of the lane's search (nothing for a lane whose search is over)."""
    if not scene.searches_for_roots:
        return lane
    gap, slope, curvature = with_curvatures(scene.gaps_along_flight(lane.profile, lane.t))
    t, index, done = root_step(gap, slope, lane.bounds, lane.t, curvature, checks_its_bounds(scene))
    searching = ~lane.found
    return lane._replace(
        t=jnp.where(searching, t, lane.t),
        index=jnp.where(searching, index, lane.index),
        found=lane.found | done,
        steps=lane.steps + searching.astype(jnp.int32),
    )


def end_flight(scene, lane: Lane, constants: Any) -> Collision:
    """The ``Collision`` of a lane whose search is over (or hit the step bound), as ``advance_components``."""
    t = lane.t
    kicked, contact = scene.collide_at(lane.state, jnp.where(jnp.isfinite(t), t, 0.0), lane.index, constants)
    refused = refused_search(scene, lane.index) if scene.searches_for_roots else None
    return finish_scene_step(scene, lane.state, kicked, t, contact, lane.found, refused)


def end_flight_tangent(scene, lane: Lane, constants: Any, tangent: tuple) -> tuple:
    """The collision map's tangent (``jb.tangent_map``, ``flow=False``) applied to ``tangent``, at a lane
    whose contact was found; components in and out.

    The contact time's derivative is implicit for a searched root
    (``dt = -(grad g . w) / g'`` at the root, as ``searched_contact_time``'s
    rule) and direct for a closed form; then the flight to the contact and
    the impulse are differentiated along ``(w, dt)``. Pure elementwise work,
    so it runs inside the Pallas kernel too.
    """
    state, t, index = lane.state, lane.t, lane.index
    reached = jnp.isfinite(t)
    t_safe = jnp.where(reached, t, 0.0)
    if scene.searches_for_roots:

        def gap_at_root(s):
            return select(scene.gaps_along_flight(scene.root_search(s)[0], t_safe)[0], index)

        _, gap_tangent = jax.jvp(gap_at_root, (state,), (tangent,))
        slope = select(scene.gaps_along_flight(scene.root_search(state)[0], t_safe)[1], index)
        t_tangent = jnp.where(reached & (slope != 0.0), -gap_tangent / jnp.where(slope != 0.0, slope, 1.0), 0.0)
    else:
        _, t_tangent = jax.jvp(lambda s: scene.closed_form_contact(s, constants)[0], (state,), (tangent,))
        t_tangent = jnp.where(reached, t_tangent, 0.0)
    _, new_tangent = jax.jvp(
        lambda s, tt: scene.collide_at(s, tt, index, constants)[0], (state, t_safe), (tangent, t_tangent)
    )
    return where(reached, new_tangent, tangent)


def tree_where(condition, if_true, if_false):
    """``jnp.where`` leaf by leaf over two pytrees of one structure."""
    return jax.tree.map(lambda a, b: jnp.where(condition, a, b), if_true, if_false)


def end_and_begin(scene, lane: Lane, active: jax.Array, constants: Any):
    """A lane whose search is over (or out of steps) applies its impulse and begins its next flight.

    ``active = False`` freezes the lane (its orbit has all the collisions it
    was asked for). Returns ``(lane, collided, collision)``: whether the lane
    completed a collision, and that ``Collision``.
    """
    collided = active & (lane.found | (lane.steps >= MAX_ROOT_STEPS))
    collision = end_flight(scene, lane, constants)
    lane = tree_where(collided, begin_flight(scene, collision.state, constants), lane)
    return lane, collided, collision
