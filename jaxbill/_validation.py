"""Eager checks at the API boundary: bad input raises ValueError naming what is wrong."""

from __future__ import annotations

import operator

import jax
import numpy as np

from ._scene import WALL_TOLERANCE


def is_concrete(x) -> bool:
    return not isinstance(x, jax.core.Tracer)


def check_count(name: str, value, minimum: int, meaning: str) -> int:
    """``value`` as a Python int ``>= minimum``, or ValueError naming ``name``."""
    kind = "non-negative" if minimum == 0 else "positive" if minimum == 1 else f">= {minimum}"
    try:
        count = operator.index(value)
    except TypeError:
        raise ValueError(f"{name} must be a {kind} integer ({meaning}); got {value!r}") from None
    if count < minimum:
        raise ValueError(f"{name} must be a {kind} integer ({meaning}); got {count}")
    return count


def check_orbit_length(n) -> int:
    return check_count("n", n, 0, "number of collisions")


def check_state(scene, state) -> None:
    """Raise ValueError unless ``state`` (shape ``(S,)`` or ``(B, S)``) is a valid start."""
    size, layout = scene.state_size, scene.state_layout
    s = np.asarray(state)
    if s.ndim not in (1, 2) or s.shape[-1] != size:
        raise ValueError(f"state must have shape ({size},) or (B, {size}) = {layout}; got shape {s.shape}")
    if not np.issubdtype(s.dtype, np.number) or np.iscomplexobj(s):
        raise ValueError(f"state must be real numbers; got dtype {s.dtype}")
    s = s.astype(np.float64)
    if not np.all(np.isfinite(s)):
        raise ValueError("state must be finite: it contains NaN or inf")
    scene.check_state_values(s)
    # The scene's own geometry, evaluated eagerly: the same gaps and normal
    # velocities the collision map uses.
    gaps = np.asarray(scene.gaps(s))
    speeds = np.asarray(scene.approach_speeds(s))
    wall = WALL_TOLERANCE * np.asarray(scene.gap_scale, dtype=np.float64)[..., None]
    for index, name in enumerate(scene.gap_names):
        outside = gaps[..., index] < -wall[..., 0]
        if np.any(outside):
            raise ValueError(
                f"state puts {name} outside {scene.wall_name}; "
                f"first offending state: {np.atleast_2d(s)[np.argmax(np.atleast_1d(outside))].tolist()}"
            )
        on_wall = gaps[..., index] <= wall[..., 0]
        if np.any(on_wall & (speeds[..., index] >= 0)):
            raise ValueError(
                f"state puts {name} on {scene.wall_name} without moving inwards: an end may touch "
                "a wall only as just after a collision; move it inside"
            )
