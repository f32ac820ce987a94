"""The event solve both diffrax checkers share: a free flight integrated step by step up to the first wall
event, and every step's gaps at both its ends, for the certification that no wall was crossed unseen.

Each checker gives its flight's vector field and event conditions (``jaxbill._check.checker``: the smallest
gap of a column; ``jaxbill._check.walls``: one condition per gap) and certifies the steps with its own bound
on the gaps' second derivatives (``jaxbill._check.report.certified_positive``).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import diffrax
import jax
import jax.numpy as jnp
import optimistix as optx


class SteppedFlight(NamedTuple):
    """A flight's accepted steps, padded to the solve's step budget.

    ``ts, ys`` the ends of the steps (``inf`` past the last); ``valid`` which
    steps were taken; ``last`` the index of the last one (the event's, where
    there was one); ``t_start, y_start, t_end, y_end`` each step's start and end
    (a padding step runs from 0 to 0 at ``y0``); ``result`` diffrax's
    ``RESULTS``; ``event_mask`` which event condition fired.
    """

    ts: jax.Array
    ys: jax.Array
    valid: jax.Array
    n_steps: jax.Array
    last: jax.Array
    t_start: jax.Array
    y_start: jax.Array
    t_end: jax.Array
    y_end: jax.Array
    result: Any
    event_mask: Any


def solve_to_event(
    vector_field, y0, *, t1, dt0, dtmax, solver, rtol, atol, root_tol, max_steps, conditions, args=None
) -> SteppedFlight:
    """Integrate ``dy/dt = vector_field(t, y, args)`` from ``y0`` at ``t = 0`` until an event of
    ``conditions`` (one function, or a list), ``t1`` or ``max_steps`` steps, saving every step; the event's
    time by Newton to ``root_tol`` (relative), a condition's sign change in either direction."""
    event = diffrax.Event(conditions, root_finder=optx.Newton(rtol=root_tol, atol=root_tol), direction=False)
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(vector_field),
        solver,
        t0=0.0,
        t1=t1,
        dt0=dt0,
        y0=y0,
        args=args,
        stepsize_controller=diffrax.PIDController(rtol=rtol, atol=atol, dtmax=dtmax),
        saveat=diffrax.SaveAt(steps=True),
        event=event,
        max_steps=max_steps,
        throw=False,
    )
    ts, ys = sol.ts, sol.ys
    assert ts is not None and ys is not None  # SaveAt(steps=True) saves both
    valid = jnp.isfinite(ts)
    n_steps = jnp.sum(valid)
    return SteppedFlight(
        ts=ts,
        ys=ys,
        valid=valid,
        n_steps=n_steps,
        last=jnp.maximum(n_steps - 1, 0),
        t_start=jnp.concatenate([jnp.zeros(1), ts[:-1]]),
        y_start=jnp.concatenate([y0[None], ys[:-1]]),
        t_end=jnp.where(valid, ts, 0.0),
        y_end=jnp.where(valid[:, None], ys, y0),
        result=sol.result,
        event_mask=sol.event_mask,
    )


def gaps_at_step_ends(gaps_and_slopes, flight: SteppedFlight, zero_tol):
    """``(f0, p0, f1, p1)``: every step's gaps and their slopes at its start and end, ``(steps, gaps)`` each.

    A gap within ``zero_tol`` of zero at the flight's start is the one that
    just bounced, zero to rounding: it counts as 0.
    """
    f0, p0 = jax.vmap(gaps_and_slopes)(flight.y_start)
    f1, p1 = jax.vmap(gaps_and_slopes)(flight.y_end)
    first = (jnp.arange(flight.ts.shape[0]) == 0)[:, None]
    f0 = jnp.where(first & (f0 > -zero_tol), jnp.maximum(f0, 0.0), f0)
    return f0, p0, f1, p1
