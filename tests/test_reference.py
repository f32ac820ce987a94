"""jaxbill's stick-in-a-circle collision map against an independent mpmath reference.

The reference (``tests/mpmath_reference.py``) is written from the physics
alone, at 50 digits, with its own rigorous first-root isolation. Its orbits
for the cases in ``tests/make_reference_data.py`` are cached in
``tests/data/reference_orbits.json`` together with each case's chaos horizon
(see the generator's docstring): the number of leading collisions over which
two exact orbits started ``1e-15`` (relative) apart stay within ``1e-11``.

* ``test_orbit_matches_reference``: ``jaxbill.orbit`` agrees with the reference
  to ``1e-10`` (scaled metric ``collision_errors``) with identical contact codes
  on the first ``min(50, horizon)`` collisions; every well-conditioned case has
  a horizon of at least 10, so no comparison is vacuous.
* ``test_one_step_map_matches_reference``: at every one of the 50 collisions,
  the reference restarted from jaxbill's own float64 state reproduces jaxbill's
  next collision (flight time, contact, state) to ``3e-13`` (``1e-11`` for a
  grazing hit), plus the rounding of the contact angle. This checks each
  collision with only its local conditioning, beyond the chaos horizon too.
* The remaining tests check the reference itself against things it does not
  use: closed forms for the lens and the circle, the impulse as a mass-weighted
  reflection with a numerically differentiated gap, dense sampling for missed
  roots, time reversal, and the cache against the generator.
"""

from __future__ import annotations

import functools
import json
import os
import sys

import mpmath
import numpy as np
import pytest
from mpmath import mp, mpf

_HERE = os.path.dirname(os.path.abspath(__file__))
if _HERE not in sys.path:  # the helpers live next to this file
    sys.path.insert(0, _HERE)

import make_reference_data as gen  # noqa: E402
import mpmath_reference as ref  # noqa: E402

with open(gen.DATA_PATH) as _f:
    _DATA = json.load(_f)
DATA = {c["name"]: c for c in _DATA["cases"]}
NAMES = list(DATA)
TOL = gen.AGREEMENT_TOL  # 1e-10
# One collision from jaxbill's own state carries only that collision's conditioning (docs/accuracy.md):
# 3e-13, measured up to 3e-14 over every collision of the well-conditioned cases that graze nothing;
# a grazing hit's contact time moves by dg / g' with g' far below its usual size: 1e-11 (measured
# up to 3.6e-13, as the ellipse's and the walls' grazing hits, up to 1e-12).
ONE_STEP_TOL = 3e-13
GRAZING_HIT_TOL = 1e-11


def _inertia(c):
    i = c["inertia"]
    return float("inf") if i == "inf" else i


def _args(c):
    return (c["R"], c["ell"], c["mass"], _inertia(c))


def _scales(c):
    return gen.scales(*_args(c), c["state0"])


def _reference(c):
    """Cached orbit as mpf (30 digits is plenty to compare with float64)."""
    times = [mpf(t) for t in c["times"]]
    states = [[mpf(v) for v in s] for s in c["states"]]
    return times, states, list(c["contacts"])


@functools.cache
def _jaxbill_orbit(name):
    jb = pytest.importorskip("jaxbill")
    import jax.numpy as jnp

    c = DATA[name]
    R, ell, mass, inertia = _args(c)
    scene = jb.StickInCircle(R=R, ell=ell, mass=mass, inertia=inertia)
    orb = jb.orbit(scene, jnp.asarray(c["state0"], dtype=jnp.float64), c["n"])
    t = np.asarray(orb.t, dtype=np.float64)
    s = np.asarray(orb.state, dtype=np.float64)
    k = np.asarray(orb.contact).astype(int)
    return t, s, k


def _first_bad(errs, tol):
    return next(((j, e) for j, e in enumerate(errs) if not e <= tol), None)


# ---------------------------------------------------------------------------
# the cached data and its horizons
# ---------------------------------------------------------------------------
def test_cases_cover_the_brief():
    assert [c["name"] for c in gen.CASES] == NAMES, "data file out of date: rerun make_reference_data.py"
    for case in gen.CASES:
        c = DATA[case["name"]]
        assert list(c["state0"]) == list(case["state0"])
        assert _args(c) == (case["R"], case["ell"], case["mass"], case["inertia"])
    well = [n for n in NAMES if not DATA[n]["ill_conditioned"]]
    assert len(well) >= 20


@pytest.mark.parametrize("name", NAMES)
def test_horizon_is_not_vacuous(name):
    c = DATA[name]
    if c["ill_conditioned"]:
        assert c["horizon"] >= 1, c["ill_conditioned"]
    else:
        assert c["horizon"] >= gen.MIN_HORIZON


# ---------------------------------------------------------------------------
# jaxbill against the reference
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("name", NAMES)
def test_orbit_matches_reference(name):
    c = DATA[name]
    t, s, k = _jaxbill_orbit(name)
    rt, rs, rk = _reference(c)
    m = min(c["n"], c["horizon"])
    assert t.shape == (c["n"],) and s.shape == (c["n"], 6) and k.shape == (c["n"],)
    assert list(k[:m]) == rk[:m], f"contacts differ: jaxbill {list(k[:m])} reference {rk[:m]}"
    with mp.workdps(30):
        errs = gen.collision_errors(list(t[:m]), list(s[:m]), rt[:m], rs[:m], _scales(c))
    bad = _first_bad(errs, TOL)
    assert bad is None, f"collision {bad[0]}: scaled error {bad[1]:.3g} > {TOL} (horizon {m})"


@pytest.mark.parametrize("name", NAMES)
def test_one_step_map_matches_reference(name):
    """Every collision of jaxbill's orbit, restarted in the reference from
    jaxbill's own previous float64 state.

    Tolerance: ``ONE_STEP_TOL`` (``GRAZING_HIT_TOL`` for a grazing hit) plus
    the rounding float64 must make in the contact angle, ``10 * 2^-52 *
    (|omega dt| + W T)``:

    * ``|omega dt|``: the phase ``alpha + omega dt`` is rounded relative to its
      size (a stick turning by 1e6 rad in a flight cannot know its angle
      better than ~1e-10 rad; it only matters for very fast spins);
    * ``W T`` (spin scale times time scale, ``sc = (T, L, V, W)``): the
      contact time is the root of a gap evaluated in float64 to about
      ``eps R^2``, with a slope of about ``R V``, so it is known only to about
      ``eps T``; the stick turns by ``|omega| <= W`` times that, and the
      impulse passes that error in the contact angle on to the spin after
      the collision (in units of ``W``) with a factor of order one. Derived
      from the scales, not fitted: ``W T = R sqrt(M / I)`` is ``R / ell`` for
      ``I = M ell^2``, below ``1e-11`` in total for every case except
      ``ell_1e-6_default_inertia``, whose stick spins at ``omega ~ V / ell ~
      1e6``: there it is ``10 eps R / ell = 4.4e-9`` (the case's
      ``ill_conditioned`` note), and restarted collisions were measured to
      deviate by up to ``2.2 eps R / ell`` over 300 collisions, before and
      after the impulse's rounding was changed (``9e-10`` over these 50).

    Measured beyond the rounding term: up to ``2.7e-13`` (``fast_spin_heavy_rotor``,
    an ill-conditioned case), ``3e-14`` in the others that graze nothing,
    ``3.6e-13`` in the grazing hits."""
    c = DATA[name]
    t, s, k = _jaxbill_orbit(name)
    R, ell, mass, inertia = _args(c)
    sc = _scales(c)
    T, W = sc[0], sc[3]
    prev_state, prev_t, bounced = list(c["state0"]), 0.0, ()
    for j in range(c["n"]):
        assert np.all(np.isfinite(s[j])) and np.isfinite(t[j]) and k[j] != 0, (
            f"collision {j}: jaxbill returned t={t[j]}, contact={k[j]}, state={s[j]} from state {prev_state!r}"
        )
        with mp.workdps(30):
            rt, rs, rk = ref.reference_orbit(R, ell, mass, inertia, prev_state, 1, dps=40, bounced=bounced)
            dt_lib = mpf(t[j]) - mpf(prev_t)
            e_t = float(abs(dt_lib - rt[0])) / T
            e_s = gen.collision_errors([0.0], [list(s[j])], [0.0], rs, sc)[0]
        base = GRAZING_HIT_TOL if name.startswith("graze_hit") else ONE_STEP_TOL
        tol = base + 10 * 2.0**-52 * (abs(prev_state[5] * float(rt[0])) + W * T)
        assert int(k[j]) == rk[0], f"collision {j}: contact jaxbill {k[j]} reference {rk[0]}"
        assert e_t <= tol and e_s <= tol, f"collision {j}: dt error {e_t:.3g}, state error {e_s:.3g} > {tol:.3g}"
        prev_state, prev_t = [float(v) for v in s[j]], t[j]
        bounced = (1, -1) if k[j] == 2 else (int(k[j]),)


# ---------------------------------------------------------------------------
# the reference against things it does not use
# ---------------------------------------------------------------------------
def test_cache_reproduces_from_generator():
    """The cached orbits and horizons are what the generator computes now."""
    for case in gen.CASES:
        fresh = gen.compute_case(case)
        c = DATA[case["name"]]
        assert fresh["horizon"] == c["horizon"], case["name"]
        assert fresh["contacts"] == c["contacts"], case["name"]
        with mp.workdps(30):
            e = gen.collision_errors(
                [mpf(v) for v in fresh["times"]],
                [[mpf(v) for v in r] for r in fresh["states"]],
                *_reference(c)[:2],
                _scales(c),
            )
        assert max(e) < 1e-20, case["name"]


def _lens_first_time(R, ell, state):
    """Closed form: each end moves on a line; larger root of a quadratic."""
    x, y, a, vx, vy, _ = state
    best = None
    for k in (1, -1):
        px, py = x + k * ell * mpmath.cos(a), y + k * ell * mpmath.sin(a)
        A = vx**2 + vy**2
        B = px * vx + py * vy
        C = px**2 + py**2 - R**2
        root = (-B + mpmath.sqrt(B * B - A * C)) / A
        if root > mpf("1e-30") and (best is None or root < best[0]):
            best = (root, k)
    return best


@pytest.mark.parametrize("name", [n for n in NAMES if DATA[n]["inertia"] == "inf"])
def test_reference_lens_matches_closed_form(name):
    c = DATA[name]
    R, ell = mpf(c["R"]), mpf(c["ell"])
    with mp.workdps(50):
        times, states, contacts = ref.reference_orbit(*_args(c), c["state0"], 20)
        prev, t_prev = [mpf(v) for v in c["state0"]], mpf(0)
        for j in range(20):
            dt, k = _lens_first_time(R, ell, prev)
            assert abs(t_prev + dt - times[j]) < mpf("1e-40")
            assert k == contacts[j]
            # specular reflection of the centre off the circle around -k ell u
            x, y, a, vx, vy, _ = ref.flow(prev, dt)
            nx, ny = x + k * ell * mpmath.cos(a), y + k * ell * mpmath.sin(a)
            r = mpmath.hypot(nx, ny)
            nx, ny = nx / r, ny / r
            vn = vx * nx + vy * ny
            assert abs(vx - 2 * vn * nx - states[j][3]) < mpf("1e-40")
            assert abs(vy - 2 * vn * ny - states[j][4]) < mpf("1e-40")
            prev, t_prev = states[j], times[j]


@pytest.mark.parametrize("name", [n for n in NAMES if DATA[n]["ell"] == 0.0])
def test_reference_circle_chords(name):
    """Circle billiard: every chord has the same length 2 sqrt(R^2 - b^2),
    b = |x vy - y vx| / |v|; omega and the speed never change."""
    c = DATA[name]
    with mp.workdps(50):
        times, states, _ = ref.reference_orbit(*_args(c), c["state0"], 30)
        x, y, a, vx, vy, w = [mpf(v) for v in c["state0"]]
        speed = mpmath.hypot(vx, vy)
        b = abs(x * vy - y * vx) / speed
        chord = 2 * mpmath.sqrt(mpf(c["R"]) ** 2 - b * b) / speed
        for j in range(1, 30):
            assert abs(times[j] - times[j - 1] - chord) < mpf("1e-40")
            assert states[j][5] == w
            assert abs(states[j][2] - (a + w * times[j])) < mpf("1e-40")


def _reflect_generic(R, ell, mass, inertia, state, k):
    """Mass-weighted specular reflection with a numerically differentiated gap."""
    x, y, a = state[:3]
    g = lambda X, Y, A: R**2 - (X + k * ell * mpmath.cos(A)) ** 2 - (Y + k * ell * mpmath.sin(A)) ** 2  # noqa: E731
    G = [mpmath.diff(g, (x, y, a), tuple(int(i == j) for i in range(3))) for j in range(3)]
    minv = [1 / mass, 1 / mass, 0 if mpmath.isinf(inertia) else 1 / inertia]
    qd = state[3:]
    num = sum(Gi * qi for Gi, qi in zip(G, qd))
    den = sum(Gi * Gi * mi for Gi, mi in zip(G, minv))
    return [qi - 2 * num / den * mi * Gi for qi, mi, Gi in zip(qd, minv, G)]


@pytest.mark.parametrize("name", ["paper_l1.0_a", "inertia_div200_l1.9", "mass0.25_inertia0.7", "paper_lens_l1.5_b"])
def test_reference_impulse_is_mass_weighted_reflection(name):
    c = DATA[name]
    with mp.workdps(50):
        R, ell, mass, inertia = ref._params(*_args(c))
        times, states, contacts = ref.reference_orbit(*_args(c), c["state0"], 10)
        prev, t_prev = [mpf(v) for v in c["state0"]], mpf(0)
        for j in range(10):
            at_contact = ref.flow(prev, times[j] - t_prev)
            assert contacts[j] in (1, -1)
            new_qd = _reflect_generic(R, ell, mass, inertia, at_contact, contacts[j])
            for got, want in zip(states[j][3:], new_qd):
                assert abs(got - want) < mpf("1e-30")
            prev, t_prev = states[j], times[j]


@pytest.mark.parametrize(
    "name", ["paper_l1.0_a", "fast_spin_l1.9", "fast_spin_l1.0_light", "graze_miss_2e-8_l1.9_a", "ell_1.9999"]
)
def test_reference_misses_no_root(name):
    """Dense float64 sampling of both gaps along every flight finds no
    penetration the reference skipped."""
    c = DATA[name]
    R, ell = c["R"], c["ell"]
    times, states, _ = _reference(c)
    prev, t_prev = [float(v) for v in c["state0"]], 0.0
    for j in range(len(times)):
        dt = float(times[j]) - t_prev
        x, y, a, vx, vy, w = prev
        m = max(2000, int(40 * abs(w) * dt))
        tt = np.linspace(0.0, dt, m)[1:-1]
        for k in (1, -1):
            px = x + vx * tt + k * ell * np.cos(a + w * tt)
            py = y + vy * tt + k * ell * np.sin(a + w * tt)
            assert np.all(px * px + py * py < R * R * (1 + 1e-12)), (j, k)
        prev, t_prev = [float(v) for v in states[j]], float(times[j])


@pytest.mark.parametrize("name", ["paper_l1.1_a", "inertia_div100_l1.9", "paper_lens_l1.5_a", "graze_hit_2e-8_l1.9_b"])
def test_reference_time_reversal(name):
    """From the middle of flight n-1 -> n, reversing v and omega retraces the
    collisions in reverse order."""
    c = DATA[name]
    n = 12
    with mp.workdps(50):
        times, states, contacts = ref.reference_orbit(*_args(c), c["state0"], n)
        mid = ref.flow(states[n - 2], (times[n - 1] - times[n - 2]) / 2)
        rev = mid[:3] + [-v for v in mid[3:]]
        rt, rs, rk = ref.reference_orbit(*_args(c), rev, n - 1)
        t_mid = (times[n - 1] + times[n - 2]) / 2
        for i in range(n - 1):
            j = n - 2 - i
            assert abs(t_mid - rt[i] - times[j]) < mpf("1e-35")
            assert rk[i] == contacts[j]
        # back at the start: reversed initial state after the final flight
        back = ref.flow(rs[n - 2], t_mid - rt[n - 2])
        start = [mpf(v) for v in c["state0"]]
        for i in range(3):
            assert abs(back[i] - start[i]) < mpf("1e-35")
        for i in range(3, 6):
            assert abs(back[i] + start[i]) < mpf("1e-35")


# ---------------------------------------------------------------------------
# exact corners: both ends reach the wall at the same instant
# ---------------------------------------------------------------------------
# R = 5, ell = 3, alpha = 0: the ends (+-3, 4) of a stick centred at (0, 4) are
# both on the circle, exactly in float64. A centre starting at (-1, 0) with
# velocity (0.25, 1) (dyadic numbers: no rounding anywhere on the way) gets
# there at t = 4 with omega = 0, so a lens and a rotor both hit with the two
# ends at once. Approach speeds 0.95 (P1) and 0.65 (P2): no tie. With I = 2 the
# alternation takes four impulses (P1, P2, P1, P2).
EXACT_CORNERS = [
    ("lens_top", float("inf"), [-1.0, 0.0, 0.0, 0.25, 1.0, 0.0]),
    ("lens_top_mirror", float("inf"), [1.0, 0.0, 0.0, -0.25, 1.0, 0.0]),
    ("lens_bottom", float("inf"), [-1.0, 0.0, 0.0, 0.25, -1.0, 0.0]),
    ("rotor_default_inertia", None, [-1.0, 0.0, 0.0, 0.25, 1.0, 0.0]),
    ("rotor_inertia2_four_impulses", 2.0, [-1.0, 0.0, 0.0, 0.25, 1.0, 0.0]),
]


def _merge_same_instant(t, s, k, T):
    """Fold collisions at the same instant (|dt| <= 1e-12 T) into one event with
    contact 2 and the state after the last impulse, whatever bookkeeping the
    library uses for the follow-up impulses of a corner."""
    out_t, out_s, out_k = [], [], []
    for tj, sj, kj in zip(t, s, k):
        if out_t and abs(tj - out_t[-1]) <= 1e-12 * T:
            out_s[-1], out_k[-1] = sj, 2
        else:
            out_t.append(tj), out_s.append(sj), out_k.append(int(kj))
    return out_t, out_s, out_k


@pytest.mark.parametrize("label,inertia,state0", EXACT_CORNERS, ids=[e[0] for e in EXACT_CORNERS])
def test_exact_corner_matches_reference(label, inertia, state0):
    jb = pytest.importorskip("jaxbill")
    import jax.numpy as jnp

    R, ell, n = 5.0, 3.0, 8
    rt, rs, rk = ref.reference_orbit(R, ell, 1.0, inertia, state0, n)
    assert rk[0] == 2 and rt[0] == 4
    orb = jb.orbit(jb.StickInCircle(R=R, ell=ell, mass=1.0, inertia=inertia), jnp.asarray(state0), n + 6)
    sc = gen.scales(R, ell, 1.0, inertia, state0)
    t, s, k = _merge_same_instant(
        list(np.asarray(orb.t)), list(np.asarray(orb.state)), list(np.asarray(orb.contact)), sc[0]
    )
    m = 6
    assert len(t) >= m
    assert k[:m] == rk[:m]
    with mp.workdps(30):
        errs = gen.collision_errors(t[:m], s[:m], rt[:m], rs[:m], sc)
    bad = _first_bad(errs, TOL)
    assert bad is None, f"collision {bad[0]}: scaled error {bad[1]:.3g} > {TOL}"
