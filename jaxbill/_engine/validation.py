"""Eager checks at the API boundary: bad input raises ValueError naming what is wrong.

Two kinds of check. *Static* ones (float64 enabled, the state's shape and
dtype, an unbatched scene) depend only on what ``jit`` knows at trace time, so
they raise under ``jit`` too. *Value* checks run only on concrete input; inside
``jit``/``vmap`` the scenes' ``is_valid`` poisons the results with NaN instead.
"""

from __future__ import annotations

import operator
import weakref

import jax
import jax.numpy as jnp
import numpy as np
from jax.core import Tracer

# Relative tolerance on a contact gap (in units of ``Scene.gap_scale``): an end
# this far outside a wall is "through the wall"; this close to it, "on the wall".
# Defined here, where the checks use it; ``jaxbill._scenes.protocols`` re-exports it.
WALL_TOLERANCE = 1e-12

# Counts of collisions whose per-collision results are kept (an orbit's states,
# a checker's collisions, seeds): 2**31 - 1 of them would already take 100 GB.
MAX_STORED_COUNT = 2**31 - 1
# Counts of anything else (a loop that keeps nothing per step): int64.
MAX_COUNT = 2**63 - 1


def is_concrete(x) -> bool:
    return not isinstance(x, Tracer)


# The scenes that passed ``scene.check()``, by identity: id -> weak reference.
_CHECKED_SCENES: dict[int, weakref.ref] = {}


def check_scene(scene) -> None:
    """``scene.check()``, once per scene object.

    A scene is a frozen ``equinox.Module``; with JAX arrays for leaves nothing
    in it can change, and a scene with other leaves (``eqx.tree_at``) is a
    new object. Checking its parameters at every call cost each call a little,
    and more just after a long orbit had evicted the interpreter from the
    caches: the lens's and the circle's orbits of 2e5 collisions ran
    measurably faster without it (``benchmarks/HISTORY.md``).
    """
    key = id(scene)
    known = _CHECKED_SCENES.get(key)
    if known is not None and known() is scene:
        return
    # A scene's own checks compute with its (concrete) parameters; under a trace, jnp would make
    # tracers of them, which the checks cannot read.
    with jax.ensure_compile_time_eval():
        scene.check()
    if all(isinstance(leaf, jax.Array) for leaf in jax.tree_util.tree_leaves(scene)):

        def forget(reference, key=key):
            if _CHECKED_SCENES.get(key) is reference:
                del _CHECKED_SCENES[key]

        _CHECKED_SCENES[key] = weakref.ref(scene, forget)


def check_parameter(name: str, value: np.ndarray, ok: np.ndarray, valid: str) -> None:
    """ValueError naming ``name``, its valid range and (up to 4) offending values, unless ``ok`` everywhere."""
    if not np.all(ok):
        # A scalar parameter prints as itself; a batch as (up to 4 of) its offending values.
        bad = value[~ok].ravel()[:4].tolist() if value.ndim else value.item()
        raise ValueError(f"{name} must be {valid}; got {bad}")


def require_x64() -> None:
    """RuntimeError unless JAX computes in float64 (``jax_enable_x64``).

    ``import jaxbill`` turns it on; turned off afterwards (or in a
    ``jax.enable_x64(False)`` context), every array would silently be float32,
    below the library's own wall tolerance of ``1e-12 R^2``.
    """
    if jax.dtypes.canonicalize_dtype(jnp.float64) != jnp.float64:
        raise RuntimeError(
            "jaxbill computes in float64, but jax_enable_x64 is off (JAX would silently use float32): "
            'call jax.config.update("jax_enable_x64", True) before using jaxbill'
        )


def real_parameter(name: str, value) -> np.ndarray:
    """A concrete parameter as a float64 array, or ValueError naming it (strings, complex, objects)."""
    try:
        array = np.asarray(value)
    except (TypeError, ValueError) as error:  # a ragged list
        raise ValueError(f"{name} must be a real number or an array of them; got {value!r} ({error})") from None
    if array.dtype.kind not in "iuf":
        raise ValueError(f"{name} must be a real number or an array of them; got {value!r} (dtype {array.dtype})")
    return array.astype(np.float64)


def broadcast_parameters(**parameters) -> None:
    """ValueError naming the parameters unless their shapes broadcast together (``None`` skipped)."""
    shapes = {name: np.shape(v) for name, v in parameters.items() if v is not None}
    try:
        np.broadcast_shapes(*shapes.values())
    except ValueError:
        listed = ", ".join(f"{name} {shape}" for name, shape in shapes.items())
        raise ValueError(
            f"parameters must be scalars or arrays of one common shape (B,); got shapes {listed}"
        ) from None


def check_count(name: str, value, minimum: int, meaning: str, maximum: int = MAX_COUNT) -> int:
    """``value`` as a Python int in ``[minimum, maximum]``, or ValueError naming ``name``.

    Booleans are refused (``True`` is an int to Python, but never a count).
    """
    kind = "non-negative" if minimum == 0 else "positive" if minimum == 1 else f">= {minimum}"
    if isinstance(value, (bool, np.bool_)) or (isinstance(value, np.ndarray) and value.dtype == bool):
        raise ValueError(f"{name} must be a {kind} integer ({meaning}); got the boolean {value!r}")
    try:
        count = operator.index(value)
    except TypeError:
        raise ValueError(f"{name} must be a {kind} integer ({meaning}); got {value!r}") from None
    if count < minimum:
        raise ValueError(f"{name} must be a {kind} integer ({meaning}); got {count}")
    if count > maximum:
        raise ValueError(f"{name} must be at most {maximum} ({meaning}); got {count}")
    return count


def check_orbit_length(n) -> int:
    return check_count("n", n, 0, "number of collisions", MAX_STORED_COUNT)


def _dtype(x):
    return x.dtype if hasattr(x, "dtype") else np.asarray(x).dtype


def check_state_static(scene, state, *, name: str = "state", single: bool = False) -> None:
    """ValueError unless ``state`` has a real dtype and shape ``(S,)`` (or ``(B, S)``).

    Uses only the shape and dtype, which are static under ``jit``: a complex
    state is refused, not cast, and a wrong shape names the state instead of
    failing in a broadcast deep inside JAX.
    """
    size, layout = scene.state_size, scene.state_layout
    dtype = _dtype(state)
    if not (np.issubdtype(dtype, np.floating) or np.issubdtype(dtype, np.integer)):
        raise ValueError(f"{name} must be real numbers; got dtype {dtype}")
    shape = np.shape(state)
    if len(shape) not in (1, 2) or shape[-1] != size:
        one = f" (here one state, ({size},))" if single else ""
        raise ValueError(f"{name} must have shape ({size},) or (B, {size}) = {layout}{one}; got shape {shape}")
    if single and len(shape) != 1:
        raise ValueError(
            f"{name} must be one state of shape ({size},) here; got a batch of shape {shape}: "
            "use jb.orbit, or jax.vmap(jb.collide, in_axes=(None, 0))"
        )


def check_last_axis(scene, states, name: str = "states") -> None:
    """ValueError unless ``states`` is ``(..., S)`` real numbers (static: under ``jit`` too).

    JAX clamps out-of-range indices, so without this ``state[..., 5]`` of a
    3-vector would silently read ``state[..., 2]``.
    """
    dtype = _dtype(states)
    if not (np.issubdtype(dtype, np.floating) or np.issubdtype(dtype, np.integer)):
        raise ValueError(f"{name} must be real numbers; got dtype {dtype}")
    shape = np.shape(states)
    if not shape or shape[-1] != scene.state_size:
        raise ValueError(f"{name} must have shape (..., {scene.state_size}) = {scene.state_layout}; got shape {shape}")


def as_states(scene, states, name: str = "states"):
    """``states`` as a JAX array ``(..., S)`` for the pure functions of states (sections, invariants).

    Static checks only (float64 on, a real dtype, the last axis ``S``): they
    hold under ``jit`` too. Values are not checked: NaN in gives NaN out.
    """
    require_x64()
    check_last_axis(scene, states, name)
    return jnp.asarray(states)


def check_unbatched_scene(scene) -> None:
    """ValueError for a batch of scenes (parameters of shape ``(B,)``), meant for ``jax.vmap``."""
    shapes = {np.shape(leaf) for leaf in jax.tree_util.tree_leaves(scene)}
    if any(shape != () for shape in shapes):
        raise ValueError(
            f"scene is a batch of scenes (parameters of shape {sorted(shapes, key=len)[-1]}): map over it with "
            "jax.vmap(..., in_axes=(0, ...)) (e.g. jax.vmap(jb.orbit, in_axes=(0, None, None)))"
        )


def motion_is_representable(v, w2, energy, length):
    """Traceable: the velocities' squares are ordinary float64 numbers.

    ``v``: ``(..., D)`` the centre's velocity; ``w2``: ``(...)`` the squared
    angular speed; ``energy``: ``(...)``; ``length``: the scene's largest
    length. Required: a finite energy, finite ``|v|^2 L^2`` and ``|w|^2 L^2``
    (the collision times square them), and ``|v|^2`` a normal number unless
    ``v`` is exactly 0 (``|v| = 1e-170`` squares to 0: such a stick would
    "never reach the wall").
    """
    v = jnp.asarray(v)
    v2 = jnp.sum(v * v, axis=-1)
    big = jnp.maximum(length, 1.0) ** 2
    small = jnp.minimum(length, 1.0) ** 2
    tiny = np.finfo(np.float64).tiny
    resolved = (v2 * small >= tiny) | jnp.all(v == 0.0, axis=-1)
    return jnp.isfinite(energy) & jnp.isfinite(v2 * big) & jnp.isfinite(w2 * big) & resolved


def on_wall_not_inwards(gaps, speeds):
    """Traceable: which states have an end on (or through) a wall that is not moving away from it."""
    return jnp.any((jnp.asarray(gaps) <= 0.0) & (jnp.asarray(speeds) >= 0.0), axis=-1)


def _offending(scene, states: jax.Array):
    """Per row of ``states`` ``(B, S)``: ``(not finite (B,), motion not representable (B,), end outside
    the wall (B, G), end on the wall without moving inwards (B, G))``, from the scene's own geometry
    (the same the collision map uses)."""
    gaps, speeds = scene.gaps(states), scene.approach_speeds(states)
    return (
        ~jnp.all(jnp.isfinite(states), axis=-1),
        ~scene.motion_is_representable(states),
        gaps < -WALL_TOLERANCE * scene.gap_scale,
        (gaps <= 0.0) & (speeds >= 0.0),
    )


@jax.jit
def _all_valid(scene, states: jax.Array) -> jax.Array:
    """Whether no row of ``states`` offends: one flag comes back to the host, not every gap and speed
    of the batch (on a GPU, copying those back cost ``jb.run`` of a million lenses more than its kernel
    took: the performance page, "On a GPU")."""
    return ~jnp.any(jnp.stack([jnp.any(o) for o in _offending(scene, states)]))


@jax.jit
def _first_offending_rows(scene, states: jax.Array):
    """``_offending``'s first offending row under each check (``-1``: none); ``(G,)`` for the gaps."""

    def first(offending):
        return jnp.where(jnp.any(offending), jnp.argmax(offending), -1)

    not_finite, unrepresentable, outside, resting = _offending(scene, states)
    return first(not_finite), first(unrepresentable), jax.vmap(first, -1)(outside), jax.vmap(first, -1)(resting)


def check_state(scene, state) -> None:
    """Raise ValueError unless ``state`` (shape ``(S,)`` or ``(B, S)``) is a valid start."""
    s = np.asarray(state)
    check_state_static(scene, s)
    s = s.astype(np.float64)
    states = np.atleast_2d(s)
    if bool(_all_valid(scene, states)):
        scene.check_state_values(s)
        return
    not_finite, unrepresentable, outside, on_wall = jax.device_get(_first_offending_rows(scene, states))
    if not_finite >= 0:
        raise ValueError("state must be finite: it contains NaN or inf")
    scene.check_state_values(s)
    if unrepresentable >= 0:
        raise ValueError(
            "state's velocities must have squares that float64 represents: |v|^2 and the energy "
            "(M |v|^2 + I omega^2) / 2 finite, |v|^2 not below 1e-308 unless v = 0; rescale the "
            f"unit of time. First offending state: {states[unrepresentable].tolist()}"
        )
    for index, name in enumerate(scene.gap_names):
        if outside[index] >= 0:
            raise ValueError(
                f"state puts {name} outside {scene.wall_name}; first offending state: {states[outside[index]].tolist()}"
            )
        # On the wall: exactly at or through it (within WALL_TOLERANCE, see _offending).
        # An end a hair inside and approaching is a valid start: the map itself
        # leaves the other end so after one end's collision.
        if on_wall[index] >= 0:
            raise ValueError(
                f"state puts {name} on {scene.wall_name} without moving inwards: an end may touch "
                "a wall only as just after a collision; move it inside"
            )
