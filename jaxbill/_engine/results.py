"""Why an orbit stopped, or what went wrong: one code per orbit, beside the NaN in its arrays.

Each collision reports a status (``finish_step`` in ``jaxbill._engine.step``); an
orbit keeps the first one that is not ``FINISHED``, so its code names what
happened first, and what followed (NaN from then on) says nothing new.
"""

from __future__ import annotations

import enum
import functools

import jax
import jax.numpy as jnp


class Result(enum.IntEnum):
    """Why an orbit stopped: ``Orbit.result``, ``Run.result`` and the tangent results hold one int32 code per orbit.

    Members (their integer codes):

    * ``FINISHED`` (0): every collision asked for was computed.
    * ``INVALID_START`` (1): the initial state is not a valid start (not
      finite, an end through a wall or on it moving outwards, velocities whose
      squares overflow, invalid traced parameters: ``scene.is_valid``); every
      array of the orbit is NaN (contacts 0). Only traced input gets here:
      outside ``jit`` a bad start raises ``ValueError``.
    * ``NO_WALL`` (2): a flight never reaches a wall (a body at rest, or one
      moving along a strip): from that collision on ``dt = inf``, the contact
      is 0 and the state stays as it was.
    * ``ROOT_STEPS_EXHAUSTED`` (3): a contact-time search took
      ``MAX_ROOT_STEPS`` safe steps without proving a root: that collision
      and every later one is NaN.
    * ``NON_FINITE`` (4): a collision met a NaN or infinite value (a state
      poisoned mid-run, an overflow along a flight): NaN from there on.
    * ``BOUND_VIOLATED`` (5): a table whose curvature bounds are checked during
      the search (``jb.ConvexTable``: estimated or given ``hessian_bound``)
      showed a gap curving beyond them, so a root could have been stepped
      over: the search stopped there, NaN from there on. Give larger bounds.
    * ``ESCAPED`` (6): the orbit left the table through a hole in its
      boundary (``jb.BodyInTable(..., holes=...)``): a collision's contact
      point lay in a hole. From then on the orbit stays as it arrived there
      (the state before any impulse, the time of the exit); that collision's
      contact is ``-1`` and every later one is ``0``, with ``dt = 0``.
    * ``STOPPED`` (7): the scene's stopping condition held just after a
      collision (``jb.BodyInTable(..., stop_when=...)``): the orbit stays
      as it was then (the state after that collision's impulse, its time);
      every later collision has contact ``0`` and ``dt = 0``.

    ``ESCAPED`` and ``STOPPED`` are no failure: the orbit ended as asked.
    ``jb.Result(code)`` names a code; ``result == jb.Result.FINISHED`` tests a
    batch of them.
    """

    FINISHED = 0
    INVALID_START = 1
    NO_WALL = 2
    ROOT_STEPS_EXHAUSTED = 3
    NON_FINITE = 4
    BOUND_VIOLATED = 5
    ESCAPED = 6
    STOPPED = 7


# An orbit that ends with one of these stays where it ended (``jaxbill._engine.chunks.Bookkeeping``).
STOPPING = (Result.ESCAPED, Result.STOPPED)


def collision_status(t, search_ended, refused=None):
    """The ``Result`` of one collision whose contact time is ``t`` (``inf``: none; NaN: no proven one).

    ``search_ended``: the contact-time search ended (a proven root, no root,
    or a hopeless lane) rather than running out of steps; ``refused``: the
    scene refused a step (``jaxbill._engine.first_root.REFUSED``), or ``None``
    for a scene that never does.
    """
    status = jnp.where(jnp.isinf(t), jnp.int32(Result.NO_WALL), jnp.int32(Result.FINISHED))
    status = jnp.where(jnp.isnan(t), jnp.int32(Result.NON_FINITE), status)
    if refused is not None:
        status = jnp.where(refused, jnp.int32(Result.BOUND_VIOLATED), status)
    return jnp.where(search_ended, status, jnp.int32(Result.ROOT_STEPS_EXHAUSTED))


def has_stopped(result):
    """Whether orbits of ``result`` have ended for good (``STOPPING``): every later collision is held."""
    return functools.reduce(jnp.logical_or, [result == jnp.int32(code) for code in STOPPING])


def tangent_held(result, status):
    """Whether a tangent analysis keeps its values through a collision of ``status`` after ``result``: an orbit
    that had ended for good (``STOPPING``), or one leaving through a hole now, whose crossing is no reflection
    of the map (a stopping condition's collision is one, and counts)."""
    return has_stopped(result) | (status == jnp.int32(Result.ESCAPED))


def kept_where(held, old, new):
    """``new``, or ``old`` where ``held``, leaf by leaf (for one orbit, ``held`` a scalar)."""
    return jax.tree.map(lambda before, after: jnp.where(held, before, after), old, new)


def first_failure(result, status, collided=None):
    """``result`` after a collision of ``status`` (where ``collided``): the first code but ``FINISHED`` stays."""
    keep = result != Result.FINISHED
    if collided is not None:
        keep = keep | ~collided
    return jnp.where(keep, result, status)


def start_result(valid):
    """``FINISHED`` for a valid start (nothing went wrong yet), ``INVALID_START`` otherwise."""
    return jnp.where(valid, jnp.int32(Result.FINISHED), jnp.int32(Result.INVALID_START))
