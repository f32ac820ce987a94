"""Work against precision: jb.orbit, the diffrax checker and a scipy event loop.

Run:  python benchmarks/bench_work_precision.py [--quick] [--repeats N] [--out PATH]

Three ways to compute the first ``k`` collisions of one orbit are compared, each at
its accuracy settings, against an independent 50-digit mpmath reference
(``tests/mpmath_reference.py``):

* **jaxbill** ``jb.orbit``: the closed-form / safe-step collision map in float64. It
  has no accuracy setting (the root search always stops at a few ulps; the constant
  is private), so it is one point per case; it is timed as an eager call (which
  validates its input) and inside ``jax.jit``.
* **jb.check**: the same dynamics integrated by diffrax in the spiral-column picture,
  with an ``Event`` on the wall, for several solvers at ``rtol = atol = root_tol =
  tol`` and, for Tsit5, several largest steps (``graze_tol`` sets ``dtmax``).
* **scipy** ``solve_ivp`` with terminal events, restarted after each impulse (the loop
  of ``bench_collisions.py``), for several methods at ``rtol = atol`` and, for
  DOP853 at ``rtol = atol = 1e-3``, several largest steps.

Between collisions every body here flies in a straight line (``dq/dt = v``, ``dv/dt
= 0``), which every Runge-Kutta method integrates exactly up to rounding: the
solvers' tolerances barely matter; what limits the integrators is the event root
(``root_tol``), rounding summed over the steps, and steps long enough to jump over
a collision (then the orbit is simply wrong).

Errors, all in the orbit's natural scales (``T = R/V``, ``V = sqrt(2E/M)``, lengths in
``R``, angles in rad, spin in ``W = sqrt(2E/I)``), maxima over the first ``k``
collisions:

* *time error after k*: ``|t_i - t_i^ref| / T``; *state error after k*: the largest
  scaled component of ``state_i - state_i^ref`` (alpha compared modulo 2 pi).
  ``k`` stays inside the chaos horizon: the collision where 1e-15-relative
  perturbations of the initial state, followed exactly (mpmath), depart from the
  reference by 1e-11 (as in ``tests/make_reference_data.py``). Beyond it no float64
  code can follow the exact orbit, and pointwise errors measure chaos, not the method.
* *one-collision error*: each of the first ``k`` collisions restarted from the
  reference state rounded to float64 and compared with a 50-digit reference of that
  single flight: the method's own error, free of chaotic amplification.
* *energy / angular-momentum drift*: ``|E_i - E_0| / E_0`` and ``|L_i - L_0| /
  (M R V + sqrt(2 E I))`` (``L`` is not conserved by the static lens).

Run time is the minimum over ``--repeats`` runs after a first (compiling) call.
Scaling: ``jb.orbit`` for one orbit of 1e2 ... 1e7 collisions (1e7 as ten calls of
1e6 collisions, each starting from the last state of the one before, so that the
states of only one call are held at a time), and for 1 ... 1e5 orbits of 100
collisions each; collisions per second and the largest invariant drift (fewer timed
runs for the largest sizes: one for 1e6 and more collisions in a call). The checker
and scipy run one orbit of up to 1e3 / 1e4 collisions beside them, timed once (the
checker after a first call of the same size).

Prints markdown tables and writes every measurement as JSON (default
``benchmarks/results/work_precision.json``). Timings come from whatever machine this
runs on; on a shared machine other processes make every time longer, which is why
minima over repeats are reported. Nothing here asserts on timings.
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import pathlib
import sys
import time

import numpy as np
from scipy.integrate import solve_ivp

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(ROOT / "tests"))

import mpmath  # noqa: E402
from mpmath import mp, mpf  # noqa: E402

from bench_collisions import _make_gap, _rhs, impulse, machine_info, random_states  # noqa: E402
from make_reference_data import HORIZON_TOL, PERTURBATION, SIGNS, _perturbed  # noqa: E402
from mpmath_reference import reference_orbit  # noqa: E402

DEFAULT_OUT = HERE / "results" / "work_precision.json"
MASS = 1.0
REFERENCE_DPS = 50
COLLISIONS = 20  # k: collisions compared with the reference (capped by the chaos horizon)
REFERENCE_COLLISIONS = 50  # the reference runs past k to locate the horizon

# The paper's rotors (Figs. 1-2) and its static lens (Fig. 3); initial states from
# tests/data/reference_orbits.json (cases paper_l1.9_a, paper_l1.0_a, paper_lens_l1.5_a).
CASES = [
    dict(label="rotor ell=1.9", R=2.0, ell=1.9, inertia=None, state0=[0.03, -0.02, 0.4, 0.6, 0.25, 0.3]),
    dict(label="rotor ell=1.0", R=2.0, ell=1.0, inertia=None, state0=[0.1, 0.2, 0.3, 0.7, -0.4, 0.5]),
    dict(label="lens ell=1.5", R=2.0, ell=1.5, inertia=math.inf, state0=[0.1, 0.05, 0.3, 0.7, -0.4, 0.0]),
]

# Settings swept, full and --quick.
CHECKER_SOLVERS = {"full": ("Tsit5", "Dopri5", "Dopri8", "Bosh3"), "quick": ("Tsit5",)}
CHECKER_TOLS = {"full": (1e-5, 1e-6, 1e-9, 1e-12), "quick": (1e-12,)}  # each compiles anew
CHECKER_GRAZE_TOLS = {"full": (1e-1, 1e-2, 1e-4, 1e-6, 1e-8), "quick": (1e-2, 1e-6)}  # 1e-6: default
# The checker's "default" point: jb.check's root_tol and atol (1e-12); its rtol default is
# 1e-10, here 1e-12 like the rest (rtol has no measurable effect on a straight flight).
CHECKER_DEFAULT_TOL = 1e-12
CHECKER_DEFAULT_GRAZE = 1e-6
SCIPY_METHODS = {"full": ("RK23", "RK45", "DOP853"), "quick": ("RK45", "DOP853")}
SCIPY_RTOLS = {"full": (1e-3, 1e-6, 1e-9, 1e-12), "quick": (1e-3, 1e-12)}
SCIPY_STEP_FRACS = {"full": (0.02, 0.1, 0.5, 2.0, math.inf), "quick": (0.1, math.inf)}  # 0.1: default
# The largest step is swept at a loose rtol: at rtol = 1e-12 the error estimate, pure rounding
# noise on a straight flight, keeps the steps short by itself.
SCIPY_STEP_SWEEP_RTOL = 1e-3
SCIPY_DEFAULT_STEP_FRAC = 0.1  # bench_collisions.py: an end moves at most 0.1 R per step

# Scaling.
ONE_ORBIT_N = {"full": (10**2, 10**3, 10**4, 10**5, 10**6, 10**7), "quick": (10**2, 10**4)}
CHUNK = 10**6  # collisions per jb.orbit call in the longest runs (48 MB of states)
# --quick: the checker at the k of the work-precision runs, whose compilation it reuses.
CHECKER_ONE_ORBIT_N = {"full": (10**2, 10**3), "quick": (COLLISIONS,)}
SCIPY_ONE_ORBIT_N = {"full": (10**2, 10**3, 10**4), "quick": (10**2,)}
BATCH_SIZES = {"full": (1, 10, 100, 10**3, 10**4, 10**5), "quick": (1, 10**3)}
BATCH_COLLISIONS = 100  # per orbit: 1e5 orbits hold 1e5 x 100 x 8 doubles = 640 MB


# --------------------------------------------------------------------------------------
# Scenes, scales, invariants
# --------------------------------------------------------------------------------------
def inertia_of(case) -> float:
    """The moment of inertia: ``M ell^2`` when the case leaves it at None."""
    return MASS * case["ell"] ** 2 if case["inertia"] is None else float(case["inertia"])


def orbit_scales(case) -> dict:
    """Natural scales of the orbit from ``state0``: ``T = R/V`` (time), ``V = sqrt(2E/M)``
    (speed), ``W = sqrt(2E/I)`` (spin; ``V/R`` for the lens) and ``L_scale = M R V +
    sqrt(2 E I)`` (angular momentum)."""
    inertia = inertia_of(case)
    E = float(energy(case, np.asarray(case["state0"])))
    V = math.sqrt(2.0 * E / MASS)
    finite = math.isfinite(inertia)
    return dict(
        T=case["R"] / V,
        V=V,
        W=math.sqrt(2.0 * E / inertia) if finite else V / case["R"],
        L=MASS * case["R"] * V + (math.sqrt(2.0 * E * inertia) if finite else 0.0),
        E=E,
    )


def energy(case, states):
    """``M |v|^2 / 2 + I omega^2 / 2`` of states ``(..., 6)`` (no spin term for the lens)."""
    states = np.asarray(states)
    e = 0.5 * MASS * (states[..., 3] ** 2 + states[..., 4] ** 2)
    inertia = inertia_of(case)
    return e + (0.5 * inertia * states[..., 5] ** 2 if math.isfinite(inertia) else 0.0)


def angular_momentum(case, states):
    """``M (x vy - y vx) + I omega`` of states ``(..., 6)`` (orbital only for the lens)."""
    states = np.asarray(states)
    orbital = MASS * (states[..., 0] * states[..., 4] - states[..., 1] * states[..., 3])
    inertia = inertia_of(case)
    return orbital + (inertia * states[..., 5] if math.isfinite(inertia) else 0.0)


def invariant_drift(case, states) -> tuple[float, float | None]:
    """Largest ``|E - E0| / E0`` and ``|L - L0| / L_scale`` over states ``(..., 6)``, with
    ``E0, L0`` of ``state0`` (float64). ``L`` drift is None for the lens (not conserved)."""
    sc = orbit_scales(case)
    state0 = np.asarray(case["state0"])
    e_drift = float(np.max(np.abs(energy(case, states) - energy(case, state0)))) / sc["E"]
    if not math.isfinite(inertia_of(case)):
        return e_drift, None
    l_drift = float(np.max(np.abs(angular_momentum(case, states) - angular_momentum(case, state0)))) / sc["L"]
    return e_drift, l_drift


# --------------------------------------------------------------------------------------
# The 50-digit reference and the error metrics
# --------------------------------------------------------------------------------------
def _wrapped_angle_difference(a, b):
    """``a - b`` modulo ``2 pi``, into ``[-pi, pi]`` (mpf)."""
    d = mpf(a) - mpf(b)
    return d - 2 * mp.pi * mpmath.nint(d / (2 * mp.pi))


def scaled_errors(times, states, ref_times, ref_states, scales):
    """Per-collision scaled errors against a reference, computed in mpf arithmetic (so that
    float64 errors far below one ulp of the reference values are resolved).

    ``times`` (m,), ``states`` (m, 6): float64 or mpf; ``ref_*``: mpf, at least m long.
    Returns ``(time_error, state_error)``, float arrays (m,): ``|t - t_ref| / T`` and the
    largest of ``|dx|/R, |dy|/R, |d alpha| (mod 2 pi), |dvx|/V, |dvy|/V, |d omega|/W``.
    """
    T, V, W, R = scales["T"], scales["V"], scales["W"], scales["R"]
    time_error, state_error = [], []
    with mp.workdps(REFERENCE_DPS):
        for t, s, tr, sr in zip(times, states, ref_times, ref_states):
            time_error.append(float(abs(mpf(t) - tr)) / T)
            components = [
                float(abs(mpf(s[0]) - sr[0])) / R,
                float(abs(mpf(s[1]) - sr[1])) / R,
                float(abs(_wrapped_angle_difference(s[2], sr[2]))),
                float(abs(mpf(s[3]) - sr[3])) / V,
                float(abs(mpf(s[4]) - sr[4])) / V,
                float(abs(mpf(s[5]) - sr[5])) / W,
            ]
            state_error.append(max(components))
    return np.asarray(time_error), np.asarray(state_error)


def _reference_args(case):
    return case["R"], case["ell"], MASS, case["inertia"]


def build_reference(case, n, n_one_flight):
    """The 50-digit reference of the first ``n`` collisions, its chaos horizon and the
    one-flight references of the first ``n_one_flight`` collisions (one-collision error).

    Horizon: as in ``tests/make_reference_data.py``, the orbit is recomputed (50 digits)
    from ``state0`` with each component multiplied by ``1 + sign * 1e-15`` (two sign
    patterns); the horizon is the first collision where either departs by more than
    1e-11 (largest scaled time or state error) or changes contact. The per-collision
    departure is kept as ``chaos_floor``: what rounding the initial state alone does.

    One-flight references: from each reference state before a collision (``state0``,
    then the states after collisions 1, 2, ...), rounded to
    float64, one collision, with the end that just bounced marked as on the wall.
    """
    start = time.perf_counter()
    sc = orbit_scales(case) | dict(R=case["R"])
    with mp.workdps(REFERENCE_DPS):
        times, states, contacts = reference_orbit(*_reference_args(case), case["state0"], n, dps=REFERENCE_DPS)
        floor = np.zeros(n)
        horizon = n
        for signs in SIGNS:
            pt, ps, pc = reference_orbit(
                *_reference_args(case), _perturbed(case["state0"], signs), n, dps=REFERENCE_DPS
            )
            te, se = scaled_errors(pt, ps, times, states, sc)
            departure = np.maximum(te, se)
            floor = np.maximum(floor, departure)
            bad = np.flatnonzero((departure > HORIZON_TOL) | (np.asarray(pc) != np.asarray(contacts)))
            if bad.size:
                horizon = min(horizon, int(bad[0]))
        starts = [list(map(float, case["state0"]))] + [[float(v) for v in s] for s in states[: n_one_flight - 1]]
        bounced = [()] + [((1, -1) if c == 2 else (c,)) for c in contacts[: n_one_flight - 1]]
        one_flight = []
        for s, b in zip(starts, bounced):
            t1, s1, c1 = reference_orbit(*_reference_args(case), s, 1, dps=REFERENCE_DPS, bounced=b)
            one_flight.append((t1[0], s1[0], c1[0]))
    return dict(
        times=times,
        states=states,
        contacts=np.asarray(contacts),
        horizon=horizon,
        chaos_floor=floor,
        starts=np.asarray(starts),
        one_flight=one_flight,
        seconds=time.perf_counter() - start,
    )


def measure_errors(case, ref, k, t, contact, state):
    """Error metrics of a method's first collisions ``t`` (m,), ``contact`` (m,), ``state``
    (m, 6), ``m <= k``, against the reference (over the first ``k`` at most)."""
    sc = orbit_scales(case) | dict(R=case["R"])
    m = min(len(t), k)
    te, se = scaled_errors(t[:m], state[:m], ref["times"][:m], ref["states"][:m], sc)
    contacts_ok = bool(np.array_equal(np.asarray(contact[:m]), ref["contacts"][:m]))
    e_drift, l_drift = invariant_drift(case, state[:m]) if m else (float("nan"), None)
    return dict(
        collisions=m,
        contacts_ok=contacts_ok,
        time_error=float(te.max()) if m else float("nan"),
        state_error=float(se.max()) if m else float("nan"),
        energy_drift=e_drift,
        angular_momentum_drift=l_drift,
        time_error_by_collision=te.tolist(),
        state_error_by_collision=se.tolist(),
    )


def measure_one_collision_errors(case, ref, k, one_collision):
    """Largest one-collision error over the first ``k`` restarts.

    ``one_collision(start)`` returns ``(dt, state_after, contact)`` or None (the method
    refused, e.g. a flagged checker step). Error: max of ``|dt - dt_ref| / T`` and the
    scaled state error; a contact different from the reference's counts as ``inf``."""
    sc = orbit_scales(case) | dict(R=case["R"])
    worst, refused = 0.0, 0
    for start, (dt_ref, s_ref, c_ref) in zip(ref["starts"][:k], ref["one_flight"][:k]):
        out = one_collision(start)
        if out is None:
            refused += 1
            continue
        dt, s, c = out
        te, se = scaled_errors([dt], [s], [dt_ref], [s_ref], sc)
        worst = max(worst, math.inf if int(c) != int(c_ref) else max(te[0], se[0]))
    return dict(one_collision_error=worst, one_collision_refused=refused)


# --------------------------------------------------------------------------------------
# Timing
# --------------------------------------------------------------------------------------
def min_run_time(run, repeats):
    """Call ``run()`` once (compiles), then ``repeats`` more times; return
    ``(timing, result of the last call)`` with the minimum, all timed runs and the first call."""
    start = time.perf_counter()
    result = run()
    first = time.perf_counter() - start
    runs = []
    for _ in range(repeats):
        start = time.perf_counter()
        result = run()
        runs.append(time.perf_counter() - start)
    return dict(seconds=min(runs) if runs else first, seconds_all=runs, first_call=first), result


# --------------------------------------------------------------------------------------
# The three methods
# --------------------------------------------------------------------------------------
def make_scene(jb, case):
    return jb.StickInCircle(R=case["R"], ell=case["ell"], mass=MASS, inertia=case["inertia"])


def jaxbill_runs(jax, jb, case, ref, k, repeats):
    """``jb.orbit`` for ``k`` collisions: eagerly (validating its input) and under ``jax.jit``."""
    import jax.numpy as jnp

    scene = make_scene(jb, case)
    state0 = jnp.asarray(case["state0"])
    orbit_in_jit = jax.jit(lambda s: jb.orbit(scene, s, k))
    variants = {
        "jb.orbit (eager call)": lambda: jax.block_until_ready(jb.orbit(scene, state0, k)),
        "jb.orbit (inside jax.jit)": lambda: jax.block_until_ready(orbit_in_jit(state0)),
    }

    def one_collision(start):
        new_state, dt, contact = jb.collide(scene, jnp.asarray(start))
        return float(dt), np.asarray(new_state), int(contact)

    local = measure_one_collision_errors(case, ref, k, one_collision)
    rows = []
    for name, run in variants.items():
        timing, orb = min_run_time(run, repeats)
        errors = measure_errors(case, ref, k, np.asarray(orb.t), np.asarray(orb.contact), np.asarray(orb.state))
        rows.append(dict(method="jaxbill", line=name, settings=dict(dtype="float64"), **timing, **errors, **local))
    return rows


def checker_run(jb, scene, state0, n, solver_name, tol, graze_tol, **options):
    """``jb.check`` with one solver and ``rtol = atol = root_tol = tol`` (``options``: more
    keyword arguments of ``jb.check``)."""
    import diffrax

    solver = getattr(diffrax, solver_name)()
    return jb.check(scene, state0, n, solver=solver, rtol=tol, atol=tol, root_tol=tol, graze_tol=graze_tol, **options)


def checker_runs(jb, case, ref, k, repeats, mode, progress):
    """The diffrax checker over its settings: one line per solver sweeping ``tol``, and one
    line for Tsit5 sweeping ``graze_tol`` (the largest step) at the default tolerances.
    A setting on two lines (the defaults) is measured once."""
    import jax.numpy as jnp

    scene = make_scene(jb, case)
    state0 = jnp.asarray(case["state0"])
    settings = [
        (f"jb.check {s}, tol sweep", s, tol, CHECKER_DEFAULT_GRAZE)
        for s in CHECKER_SOLVERS[mode]
        for tol in CHECKER_TOLS[mode]
    ]
    settings += [("jb.check Tsit5, dtmax sweep", "Tsit5", CHECKER_DEFAULT_TOL, g) for g in CHECKER_GRAZE_TOLS[mode]]
    measured = {}
    rows = []
    for line, solver_name, tol, graze_tol in settings:
        key = (solver_name, tol, graze_tol)
        if key not in measured:
            measured[key] = measure_checker(jb, case, ref, k, repeats, scene, state0, *key)
            progress(
                f"{case['label']}: jb.check {solver_name} tol={tol:g} graze_tol={graze_tol:g}: "
                f"{measured[key]['seconds'] * 1e3:.1f} ms, {measured[key]['certified']}/{k} certified"
            )
        rows.append(dict(method="jb.check (diffrax)", line=line, **measured[key]))
    return rows


def measure_checker(jb, case, ref, k, repeats, scene, state0, solver_name, tol, graze_tol):
    """Run time and errors of ``jb.check`` at one setting (see ``checker_runs``)."""
    import jax.numpy as jnp

    def run():
        return checker_run(jb, scene, state0, k, solver_name, tol, graze_tol)

    timing, result = min_run_time(run, repeats)

    def one_collision(start):
        # horizon_eps=0: jb.check's chaos-horizon perturbations (1e-12 relative) push an
        # end that sits on the wall outside it, and jb.orbit then rejects them; the
        # horizon is not needed for a single collision.
        r = checker_run(jb, scene, jnp.asarray(start), 1, solver_name, tol, graze_tol, horizon_eps=0.0)
        if r.report.n_checked < 1:
            return None
        return float(r.t[0]), r.state[0], int(r.contact[0])

    errors = measure_errors(case, ref, k, result.t, result.contact, result.state)
    local = measure_one_collision_errors(case, ref, k, one_collision)
    report = result.report
    return dict(
        settings=dict(solver=solver_name, rtol=tol, atol=tol, root_tol=tol, graze_tol=graze_tol),
        certified=report.n_checked,
        flags=[f"{f.kind} at collision {f.index}" for f in report.flags],
        solver_steps=report.n_steps,
        **timing,
        **errors,
        **local,
    )


def scipy_event_orbit(case, n, method, rtol, atol, step_frac):
    """``n`` collisions by ``solve_ivp`` with terminal events on both gaps, the impulse
    applied at each event and the solve restarted (``bench_collisions.scipy_orbit`` with
    the method and the largest step as parameters).

    ``max_step = step_frac * R / (|v| + ell |omega|)`` bounds how far an end moves in one
    step; with a large one a step can pass over a short excursion through the wall, and
    the event is missed (the orbit is then wrong, not less accurate).

    Returns ``(t (m,), contact (m,), states (m, 6), solver_steps)``; ``m < n`` if a solve
    ended without an event.
    """
    R, ell = case["R"], case["ell"]
    inertia = inertia_of(case)
    events = [_make_gap(R, ell, +1), _make_gap(R, ell, -1)]
    q = np.array(case["state0"], dtype=float)
    t0 = 0.0
    times, contacts, states = [], [], []
    steps = 0
    for _ in range(n):
        speed = math.hypot(q[3], q[4]) + ell * abs(q[5])
        horizon = 100.0 * (2.0 * R) / speed  # far beyond any free flight
        sol = solve_ivp(
            _rhs,
            (t0, t0 + horizon),
            q,
            method=method,
            rtol=rtol,
            atol=atol,
            events=events,
            max_step=step_frac * R / speed,
        )
        steps += sol.t.size - 1
        if sol.status != 1:
            break
        t_event, j = min((te[0], j) for j, te in enumerate(sol.t_events) if te.size)
        end = (+1, -1)[j]
        q = impulse(sol.y_events[j][0], end, R, ell, MASS, inertia)
        t0 = t_event
        times.append(t_event)
        contacts.append(end)
        states.append(q)
    return np.asarray(times), np.asarray(contacts), np.asarray(states).reshape(-1, 6), steps


def scipy_runs(case, ref, k, repeats, mode, progress):
    """The scipy loop: one line per method sweeping ``rtol = atol`` at the default largest
    step, and one line for DOP853 sweeping the largest step at ``rtol = atol = 1e-3``.
    A setting on two lines is measured once."""
    settings = [
        (f"scipy {m}, rtol sweep", m, rtol, SCIPY_DEFAULT_STEP_FRAC)
        for m in SCIPY_METHODS[mode]
        for rtol in SCIPY_RTOLS[mode]
    ]
    settings += [("scipy DOP853, max_step sweep", "DOP853", SCIPY_STEP_SWEEP_RTOL, f) for f in SCIPY_STEP_FRACS[mode]]
    measured = {}
    rows = []
    for line, method, rtol, step_frac in settings:
        key = (method, rtol, step_frac)
        if key not in measured:
            measured[key] = measure_scipy(case, ref, k, repeats, *key)
            progress(
                f"{case['label']}: scipy {method} rtol={rtol:g} max_step_fraction={step_frac}: "
                f"{measured[key]['seconds'] * 1e3:.1f} ms"
            )
        rows.append(dict(method="scipy solve_ivp", line=line, **measured[key]))
    return rows


def measure_scipy(case, ref, k, repeats, method, rtol, step_frac):
    """Run time and errors of the scipy loop at one setting (see ``scipy_runs``)."""
    timing, (t, contact, states, steps) = min_run_time(
        lambda: scipy_event_orbit(case, k, method, rtol, rtol, step_frac), repeats
    )

    def one_collision(start):
        tt, cc, ss, _ = scipy_event_orbit(dict(case, state0=list(start)), 1, method, rtol, rtol, step_frac)
        return (tt[0], ss[0], cc[0]) if len(tt) else None

    errors = measure_errors(case, ref, k, t, contact, states)
    local = measure_one_collision_errors(case, ref, k, one_collision)
    return dict(
        settings=dict(solver=method, rtol=rtol, atol=rtol, max_step_fraction=step_frac),
        certified=len(t),
        solver_steps=steps,
        **timing,
        **errors,
        **local,
    )


# --------------------------------------------------------------------------------------
# Scaling
# --------------------------------------------------------------------------------------
def one_orbit_scaling(jax, jb, case, n_values, repeats):
    """``jb.orbit`` on one orbit for each ``n``: run time (minimum over repeats after the
    compiling call; one timed run for ``n > CHUNK``, done in chunks of ``CHUNK``
    collisions) and the largest invariant drift over the orbit."""
    import jax.numpy as jnp

    scene = make_scene(jb, case)
    state0 = jnp.asarray(case["state0"])
    rows = []
    for n in n_values:
        if n <= CHUNK:
            timing, orb = min_run_time(
                lambda: jax.block_until_ready(jb.orbit(scene, state0, n)), repeats if n < CHUNK else 1
            )
            e_drift, l_drift = invariant_drift(case, np.asarray(orb.state))
            final = np.asarray(orb.state[-1])
            del orb
        else:
            if CHUNK not in n_values:  # compile the chunk's program before the clock starts
                jax.block_until_ready(jb.orbit(scene, state0, CHUNK))
            start = time.perf_counter()
            state, e_drift, l_drift = state0, 0.0, 0.0
            for _ in range(n // CHUNK):
                orb = jax.block_until_ready(jb.orbit(scene, state, CHUNK))
                e, l_ = invariant_drift(case, np.asarray(orb.state))
                e_drift, l_drift = max(e_drift, e), None if l_ is None else max(l_drift, l_)
                state = orb.state[-1]
                del orb
            seconds = time.perf_counter() - start
            timing = dict(
                seconds=seconds,
                seconds_all=[seconds],
                first_call=None,
                note=f"{n // CHUNK} calls of {CHUNK} collisions, drift evaluation included",
            )
            final = np.asarray(state)
        rows.append(
            dict(
                method="jaxbill",
                case=case["label"],
                n=n,
                rate=n / timing["seconds"],
                **timing,
                energy_drift=e_drift,
                angular_momentum_drift=l_drift,
                final_energy_error=float(
                    abs(energy(case, final) - energy(case, np.asarray(case["state0"]))) / orbit_scales(case)["E"]
                ),
            )
        )
    return rows


def integrator_one_orbit_scaling(jb, case, checker_n, scipy_n):
    """The checker (Tsit5, defaults) and scipy (DOP853, rtol = atol = 1e-12, max_step
    0.1 R / speed) on one long orbit: run time and invariant drift.

    The checker is timed once after a first call of the same size (which compiles the
    jb.orbit programs its comparison uses); its time includes that comparison. scipy
    has nothing to compile and is timed once."""
    import jax.numpy as jnp

    scene = make_scene(jb, case)
    state0 = jnp.asarray(case["state0"])
    rows = []
    for n in checker_n:
        timing, result = min_run_time(
            lambda: checker_run(jb, scene, state0, n, "Tsit5", CHECKER_DEFAULT_TOL, CHECKER_DEFAULT_GRAZE), 1
        )
        e_drift, l_drift = invariant_drift(case, result.state)
        rows.append(
            dict(
                method="jb.check (diffrax)",
                case=case["label"],
                n=n,
                certified=result.report.n_checked,
                rate=result.report.n_checked / timing["seconds"],
                **timing,
                energy_drift=e_drift,
                angular_momentum_drift=l_drift,
            )
        )
    for n in scipy_n:
        start = time.perf_counter()
        t, _, states, _ = scipy_event_orbit(case, n, "DOP853", 1e-12, 1e-12, SCIPY_DEFAULT_STEP_FRAC)
        seconds = time.perf_counter() - start
        e_drift, l_drift = invariant_drift(case, states)
        rows.append(
            dict(
                method="scipy solve_ivp",
                case=case["label"],
                n=n,
                certified=len(t),
                seconds=seconds,
                rate=len(t) / seconds,
                energy_drift=e_drift,
                angular_momentum_drift=l_drift,
            )
        )
    return rows


def batch_scaling(jax, jb, case, batch_sizes, n, repeats, seed):
    """``jb.orbit`` on ``B`` orbits of ``n`` collisions each (seeded random valid states,
    ``bench_collisions.random_states``): run time, collisions per second and the largest
    invariant drift over all orbits (each against its own initial state)."""
    import jax.numpy as jnp

    scene = make_scene(jb, case)
    rows = []
    for B in batch_sizes:
        states0 = random_states(case["R"], case["ell"], case["inertia"], B, seed=seed + B)
        x = jnp.asarray(states0)
        timing, orb = min_run_time(
            lambda: jax.block_until_ready(jb.orbit(scene, x, n)), repeats if B * n < 10**7 else 1
        )
        states = np.asarray(orb.state)  # (B, n, 6)
        e0, l0 = energy(case, states0)[:, None], angular_momentum(case, states0)[:, None]
        e_drift = float(np.max(np.abs(energy(case, states) - e0) / e0))
        if math.isfinite(inertia_of(case)):
            scale = MASS * case["R"] * np.sqrt(2 * e0 / MASS) + np.sqrt(2 * e0 * inertia_of(case))
            l_drift = float(np.max(np.abs(angular_momentum(case, states) - l0) / scale))
        else:
            l_drift = None
        stalled = int(np.sum(np.asarray(orb.contact)[:, -1] == 0))
        del orb, states
        rows.append(
            dict(
                method="jaxbill",
                case=case["label"],
                B=B,
                n=n,
                rate=B * n / timing["seconds"],
                **timing,
                energy_drift=e_drift,
                angular_momentum_drift=l_drift,
                stalled=stalled,
            )
        )
    return rows


# --------------------------------------------------------------------------------------
# Summaries and output
# --------------------------------------------------------------------------------------
def _complete(row, k):
    return row["collisions"] == k and row.get("certified", k) == k


def headline(rows, k_of):
    """Per case and method: the run at its fastest settings and the one at its most
    accurate settings, both among the runs that returned all ``k`` collisions with the
    reference's contact sequence (a run that missed a collision computed another orbit).
    Most accurate: the smallest of ``max(time error after k, one-collision error)``; the
    time error alone, near the chaos horizon, ranks settings by how rounding happened to
    be amplified."""
    out = []
    for case in dict.fromkeys(r["case"] for r in rows):
        for method in dict.fromkeys(r["method"] for r in rows):
            mine = [
                r
                for r in rows
                if r["case"] == case and r["method"] == method and _complete(r, k_of[case]) and r["contacts_ok"]
            ]
            if not mine:
                continue
            fastest = min(mine, key=lambda r: r["seconds"])
            best = min(mine, key=lambda r: (max(r["time_error"], r["one_collision_error"]), r["seconds"]))
            out.append(dict(case=case, method=method, k=k_of[case], fastest=fastest, most_accurate=best))
    return out


def describe(settings):
    parts = []
    for key, value in settings.items():
        if key == "atol" or (key == "root_tol" and "rtol" in settings):
            continue  # swept together with rtol
        if key == "rtol" and "root_tol" in settings:
            key = "tol"
        parts.append(f"{key}={value:g}" if isinstance(value, float) else f"{key}={value}")
    return ", ".join(parts)


def fmt(x, spec=".1e"):
    """A measurement for a table: ``n/a`` for None; JSON's ``"inf"``/``"nan"`` strings read back."""
    if x is None:
        return "n/a"
    x = float(x)
    return "inf" if math.isinf(x) else format(x, spec)


def print_tables(data):
    print("## Cases and references")
    print()
    print(
        f"Chaos horizon: first collision at which 1e-15-relative perturbations of state0, followed at "
        f"{REFERENCE_DPS} digits, depart from the reference by more than {HORIZON_TOL:g} (searched up to "
        f"{REFERENCE_COLLISIONS} collisions)."
    )
    print()
    print("| case | state0 | k compared | chaos horizon | reference (s) |")
    print("|---|---|---:|---:|---:|")
    for c in data["cases"]:
        horizon = f">= {c['horizon']}" if c["horizon"] >= REFERENCE_COLLISIONS else str(c["horizon"])
        print(f"| {c['label']} | {c['state0']} | {c['k']} | {horizon} | {c['reference_seconds']:.1f} |")
    print()
    print("## Work against precision (one orbit, k collisions)")
    print()
    print(
        "Run time: minimum over repeats after a compiling call, for all k collisions. Errors: largest "
        "over the first k collisions against the 50-digit reference, scaled (time in R/V, state in R, rad, "
        "V, W). 'one-coll.': each collision restarted from the rounded reference state. jb.check's time "
        "includes its own comparison with jb.orbit."
    )
    print()
    print(
        "| case | line | settings | time (ms) | us/coll. | done | contacts | time err | state err "
        "| one-coll. err | E drift | L drift |"
    )
    print("|---|---|---|---:|---:|---:|:---:|---:|---:|---:|---:|---:|")
    for r in data["work_precision"]:
        done = r.get("certified", r["collisions"])
        print(
            f"| {r['case']} | {r['line']} | {describe(r['settings'])} | {r['seconds'] * 1e3:.2f} | "
            f"{r['seconds'] / max(done, 1) * 1e6:.0f} | {done} | {'ok' if r['contacts_ok'] else 'WRONG'} | "
            f"{fmt(r['time_error'])} | {fmt(r['state_error'])} | {fmt(r['one_collision_error'])} | "
            f"{fmt(r['energy_drift'])} | {fmt(r['angular_momentum_drift'])} |"
        )
    print()
    print("## Headline: each method at its fastest and at its most accurate settings")
    print()
    print(headline_markdown(data))
    print()
    print("## Headline: scaling")
    print()
    print(scaling_markdown(data))
    print()
    print("## Scaling: one orbit")
    print()
    print("| case | method | collisions | done | run time (s) | collisions/s | E drift (max) | L drift (max) |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for r in data["scaling_one_orbit"]:
        print(
            f"| {r['case']} | {r['method']} | {r['n']:.0e} | {r.get('certified', r['n'])} | {r['seconds']:.3g} | "
            f"{r['rate']:.3g} | {fmt(r['energy_drift'])} | {fmt(r['angular_momentum_drift'])} |"
        )
    print()
    print("## Scaling: many orbits (jb.orbit)")
    print()
    print("| case | orbits | collisions each | run time (s) | collisions/s | E drift (max) | L drift (max) | stalled |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for r in data["scaling_batch"]:
        print(
            f"| {r['case']} | {r['B']} | {r['n']} | {r['seconds']:.3g} | {r['rate']:.3g} | "
            f"{fmt(r['energy_drift'])} | {fmt(r['angular_momentum_drift'])} | {r['stalled']} |"
        )


def short_settings(row):
    """The settings of a work-precision row in a few words."""
    s = row["settings"]
    if row["method"] == "jaxbill":
        return "float64, " + ("inside jax.jit" if "jit" in row["line"] else "eager call")
    if "root_tol" in s:
        return f"{s['solver']}, tol {s['rtol']:.0e}, graze_tol {s['graze_tol']:.0e}"
    return f"{s['solver']}, rtol {s['rtol']:.0e}, max_step {float(s['max_step_fraction']):g} R/speed"


def headline_markdown(data):
    """Markdown table: each method at its fastest and most accurate settings, per case."""
    lines = [
        "| scene (k collisions) | method | fastest: settings | run time | time error | one-collision error "
        "| most accurate: settings | run time | time error | one-collision error |",
        "|---|---|---|---:|---:|---:|---|---:|---:|---:|",
    ]
    for h in data["headline"]:
        f, b = h["fastest"], h["most_accurate"]
        lines.append(
            f"| {h['case']} ({h['k']}) | {h['method']} | {short_settings(f)} | {f['seconds'] * 1e3:.2g} ms | "
            f"{fmt(f['time_error'])} | {fmt(f['one_collision_error'])} | {short_settings(b)} | "
            f"{b['seconds'] * 1e3:.2g} ms | {fmt(b['time_error'])} | {fmt(b['one_collision_error'])} |"
        )
    return "\n".join(lines)


def scaling_markdown(data):
    """Markdown table: the largest scaling runs per case (jb.orbit one orbit and batch; the
    longest checker and scipy runs)."""
    lines = [
        "| scene | jb.orbit, one orbit | collisions/s | E drift | L drift | jb.orbit, many orbits | collisions/s "
        "| E drift | jb.check, one orbit: collisions/s | scipy loop, one orbit: collisions/s |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for c in data["cases"]:

        def longest(method):
            rows = [r for r in data["scaling_one_orbit"] if r["case"] == c["label"] and r["method"] == method]
            return max(rows, key=lambda r: r["n"]) if rows else None

        one, checker, scipy_loop = longest("jaxbill"), longest("jb.check (diffrax)"), longest("scipy solve_ivp")
        batch = max((r for r in data["scaling_batch"] if r["case"] == c["label"]), key=lambda r: r["B"])
        lines.append(
            f"| {c['label']} | {one['n']:.0e} collisions in {one['seconds']:.3g} s | {one['rate']:.2g} | "
            f"{fmt(one['energy_drift'])} | {fmt(one['angular_momentum_drift'])} | "
            f"{batch['B']:.0e} x {batch['n']} in {batch['seconds']:.3g} s | {batch['rate']:.2g} | "
            f"{fmt(batch['energy_drift'])} | "
            f"{checker['rate']:.3g} ({checker['n']:.0e}) | {scipy_loop['rate']:.3g} ({scipy_loop['n']:.0e}) |"
        )
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="small sweeps and sizes (< 1 min)")
    ap.add_argument(
        "--repeats",
        type=int,
        default=None,
        help="timed runs after compilation (default 5, quick 2; at most 3 in the scaling runs)",
    )
    ap.add_argument("--out", type=pathlib.Path, default=DEFAULT_OUT, help=f"JSON output (default {DEFAULT_OUT})")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    mode = "quick" if args.quick else "full"
    repeats = max(1, args.repeats or (2 if args.quick else 5))
    scaling_repeats = min(repeats, 3)

    import jax

    import jaxbill as jb  # enables float64

    t_all = time.perf_counter()

    def progress(msg):
        print(f"  [{time.perf_counter() - t_all:6.1f}s] {msg}", file=sys.stderr, flush=True)

    print("# jaxbill work against precision" + (" (--quick: small sweeps)" if args.quick else ""))
    print()
    print(machine_info(jax))
    load_start = os.getloadavg()
    print(
        f"- load average at start (1/5/15 min): {load_start[0]:.2f} {load_start[1]:.2f} {load_start[2]:.2f}; "
        "figures come from a shared machine: other processes lengthen every time, minima over repeats "
        "are reported"
    )
    print()
    sys.stdout.flush()

    cases, wp_rows = [], []
    k_of = {}
    for case in CASES:
        ref = build_reference(case, REFERENCE_COLLISIONS, COLLISIONS)
        k = min(COLLISIONS, ref["horizon"])
        k_of[case["label"]] = k
        sc = orbit_scales(case)
        cases.append(
            dict(
                label=case["label"],
                R=case["R"],
                ell=case["ell"],
                inertia=None if case["inertia"] is None else str(case["inertia"]),
                state0=case["state0"],
                k=k,
                horizon=ref["horizon"],
                reference_dps=REFERENCE_DPS,
                reference_seconds=ref["seconds"],
                scales=sc,
                chaos_floor=ref["chaos_floor"].tolist(),
            )
        )
        progress(
            f"{case['label']}: reference of {REFERENCE_COLLISIONS} collisions, horizon {ref['horizon']} "
            f"({ref['seconds']:.1f} s)"
        )
        rows = jaxbill_runs(jax, jb, case, ref, k, repeats)
        rows += checker_runs(jb, case, ref, k, repeats, mode, progress)
        rows += scipy_runs(case, ref, k, repeats, mode, progress)
        for r in rows:
            r["case"] = case["label"]
        wp_rows += rows

    one_orbit, batch = [], []
    for case in CASES:
        one_orbit += one_orbit_scaling(jax, jb, case, ONE_ORBIT_N[mode], scaling_repeats)
        progress(f"{case['label']}: one-orbit scaling (jb.orbit) done")
        one_orbit += integrator_one_orbit_scaling(jb, case, CHECKER_ONE_ORBIT_N[mode], SCIPY_ONE_ORBIT_N[mode])
        progress(f"{case['label']}: one-orbit scaling (checker, scipy) done")
        batch += batch_scaling(jax, jb, case, BATCH_SIZES[mode], BATCH_COLLISIONS, scaling_repeats, args.seed)
        progress(f"{case['label']}: batch scaling done")

    load_end = os.getloadavg()
    data = dict(
        meta=dict(
            generator="benchmarks/bench_work_precision.py" + (" --quick" if args.quick else ""),
            date=datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
            machine=machine_info(jax),
            load_average_start=load_start,
            load_average_end=load_end,
            shared_machine_note="timings from a shared machine; minima over repeats after compilation",
            repeats=repeats,
            scaling_repeats=scaling_repeats,
            collisions_compared=COLLISIONS,
            reference=f"tests/mpmath_reference.py at {REFERENCE_DPS} digits, {REFERENCE_COLLISIONS} collisions",
            horizon_rule=f"perturbation {PERTURBATION} relative, departure > {HORIZON_TOL}",
            wall_seconds=None,
        ),
        cases=cases,
        work_precision=wp_rows,
        scaling_one_orbit=one_orbit,
        scaling_batch=batch,
    )
    data["headline"] = headline(wp_rows, k_of)
    data["meta"]["wall_seconds"] = time.perf_counter() - t_all
    print_tables(data)
    print()
    print(
        f"Wall time {data['meta']['wall_seconds']:.0f} s; load average at end (1/5/15 min): "
        f"{load_end[0]:.2f} {load_end[1]:.2f} {load_end[2]:.2f}."
    )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with open(args.out, "w") as f:
        json.dump(plain_json(data), f, indent=1, allow_nan=False)
        f.write("\n")
    print(f"wrote {args.out}")


def plain_json(x):
    """``x`` with numpy scalars and arrays as Python ones and non-finite floats as the
    strings ``"inf"``, ``"-inf"``, ``"nan"`` (standard JSON has no such numbers;
    ``float()`` reads them back)."""
    if isinstance(x, dict):
        return {k: plain_json(v) for k, v in x.items()}
    if isinstance(x, (list, tuple, np.ndarray)):
        return [plain_json(v) for v in x]
    if isinstance(x, (np.floating, np.integer, np.bool_)):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return str(x)
    return x


if __name__ == "__main__":
    main()
