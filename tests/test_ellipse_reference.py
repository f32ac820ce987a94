"""``StickInEllipse`` against the independent mpmath reference, and ``StickInCircle`` at ``a = b``.

The reference (``tests/mpmath_ellipse_reference.py``, 45 digits, its own
rigorous root isolation and the impulse as a generic mass-metric reflection)
is cached with each case's conditioning in ``tests/data/ellipse_reference.json``
by ``tests/make_ellipse_reference_data.py``.

Tolerances (scaled metric ``collision_errors``: time over ``sqrt(ab)/V``,
positions over ``sqrt(ab)``, angle in radians, velocities over ``V``, spin over
its scale):

* whole orbits: ``1e-10`` on the collisions within the horizon (where two exact
  orbits started ``1e-15`` apart stay within ``1e-11``); past it, or for an
  ill-conditioned collision (grazing hits), ``30x`` the measured spread of the
  perturbed exact orbits, as long as that is below ``1e-7``. Float64 makes
  errors of a few ``1e-16`` per collision, so ``30x`` a ``1e-15`` perturbation
  leaves room for some ten collisions' rounding;
* one collision from jaxbill's own float64 state (the reference restarted
  there), which carries only that collision's conditioning: ``2e-13`` (a
  few hundred ulps; measured up to 5e-15), and ``1e-11`` for the grazing hits,
  whose contact time moves by ``dg / g'`` with ``g'`` about ``1e-4`` of its
  usual size (measured up to 9e-13).
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
if _HERE not in sys.path:
    sys.path.insert(0, _HERE)

import make_ellipse_reference_data as gen  # noqa: E402
import mpmath_ellipse_reference as ref  # noqa: E402

jax = pytest.importorskip("jax")
jb = pytest.importorskip("jaxbill")
import jax.numpy as jnp  # noqa: E402

with open(gen.DATA_PATH) as _f:
    DATA = {c["name"]: c for c in json.load(_f)["cases"]}
NAMES = list(DATA)
TOL = gen.AGREEMENT_TOL


def _inertia(c):
    return float("inf") if c["inertia"] == "inf" else c["inertia"]


def _scene(c):
    return jb.StickInEllipse(c["a"], c["b"], c["ell"], mass=c["mass"], inertia=_inertia(c))


def _scales(c):
    return gen.scales(c["a"], c["b"], c["ell"], c["mass"], c["inertia"], c["state0"])


def _reference(c):
    return [mpf(t) for t in c["times"]], [[mpf(v) for v in s] for s in c["states"]], list(c["contacts"])


@functools.cache
def _jaxbill_orbit(name):
    c = DATA[name]
    orb = jb.orbit(_scene(c), jnp.asarray(c["state0"]), c["n"])
    return np.asarray(orb.t), np.asarray(orb.state), np.asarray(orb.contact).astype(int)


def _allowed(c, j):
    if j < c["horizon"]:
        return TOL
    return max(TOL, gen.SENSITIVITY_FACTOR * c["sensitivity"][j])


def test_data_matches_the_generator():
    assert [c["name"] for c in gen.CASES] == NAMES, "data out of date: rerun tests/make_ellipse_reference_data.py"
    for case in gen.CASES:
        c = DATA[case["name"]]
        assert c["state0"] == case["state0"]
        assert (c["a"], c["b"], c["ell"], c["mass"]) == (case["a"], case["b"], case["ell"], case["mass"])
    assert len(NAMES) >= 20
    kinds = {_scene(c).kind for c in DATA.values()}
    assert kinds == {"rotor", "static", "point"}


def test_cache_reproduces_from_the_reference():
    """Every cached orbit, horizon and sensitivity is what the mpmath reference and the generator compute
    now (about 3 s for all of them): the comparisons above are against the reference, not a stale file."""
    for case in gen.CASES:
        fresh = gen.compute_case(case)
        c = DATA[case["name"]]
        assert fresh["contacts"] == c["contacts"], case["name"]
        assert fresh["horizon"] == c["horizon"], case["name"]
        np.testing.assert_allclose(fresh["sensitivity"], c["sensitivity"], rtol=1e-6, err_msg=case["name"])
        with mp.workdps(30):
            fresh_times = [mpf(t) for t in fresh["times"]]
            fresh_states = [[mpf(v) for v in row] for row in fresh["states"]]
            errors = gen.collision_errors(fresh_times, fresh_states, *_reference(c)[:2], _scales(c))
        # 25 stored digits of a 45-digit computation
        assert max(errors) < 1e-20, f"{case['name']}: cached orbit differs from the reference by {max(errors):.3g}"


@pytest.mark.parametrize("name", NAMES)
def test_orbit_matches_reference(name):
    c = DATA[name]
    t, s, k = _jaxbill_orbit(name)
    rt, rs, rk = _reference(c)
    with mp.workdps(30):
        errs = gen.collision_errors(list(t), list(s), rt, rs, _scales(c))
    checked = [j for j in range(c["n"]) if _allowed(c, j) <= gen.SENSITIVE_LIMIT]
    # At least the first collision of every case, and the first few of every well-conditioned one.
    assert checked[:1] == [0]
    assert len(checked) >= min(c["n"], max(c["horizon"], 1))
    for j in checked:
        assert k[j] == rk[j], f"collision {j}: contact {k[j]} != reference {rk[j]}"
        assert errs[j] <= _allowed(c, j), f"collision {j}: scaled error {errs[j]:.3g} > {_allowed(c, j):.3g}"


def test_well_conditioned_cases_agree_to_1e_12_on_first_collisions():
    """Where the orbit is well conditioned, the first three collisions agree far below the 1e-10 bound."""
    worst = 0.0
    for name in NAMES:
        c = DATA[name]
        if c["horizon"] < 3:
            continue
        t, s, _ = _jaxbill_orbit(name)
        rt, rs, _ = _reference(c)
        with mp.workdps(30):
            worst = max(worst, *gen.collision_errors(list(t[:3]), list(s[:3]), rt[:3], rs[:3], _scales(c)))
    assert worst <= 1e-12


ONE_STEP = [
    "ratio_3",
    "fast_spin",
    "graze_miss_rotor",
    "graze_hit_rotor",
    "graze_hit_static",
    "graze_hit_point",
    "static_near_corner_1e-7",
    "longer_than_minor",
    "mass0.3_inertia0.05",
    "point_ratio_1.5_spinning",
]


def _one_step_tolerance(name):
    return 1e-11 if name.startswith("graze_hit") else 2e-13


@pytest.mark.parametrize("name", ONE_STEP)
def test_one_step_map_matches_reference(name):
    """Every collision of the cached run, beyond the horizon too: the reference restarted from jaxbill's state."""
    c = DATA[name]
    t, s, k = _jaxbill_orbit(name)
    sc = _scales(c)
    args = (c["a"], c["b"], c["ell"], c["mass"], c["inertia"])
    for j in range(c["n"] - 1):
        bounced = (1, -1) if k[j] == 2 else (int(k[j]),)
        rt, rs, rk = ref.reference_orbit(*args, list(s[j]), 1, dps=40, bounced=bounced)
        with mp.workdps(30):
            (err,) = gen.collision_errors([t[j + 1] - t[j]], [s[j + 1]], rt, rs, sc)
        assert k[j + 1] == rk[0], f"collision {j + 1}: contact {k[j + 1]} != {rk[0]}"
        assert err <= _one_step_tolerance(name), f"collision {j + 1}: scaled error {err:.3g}"


@pytest.mark.parametrize("name", [n for n in NAMES if n.startswith("circle_")])
def test_equal_axes_match_stick_in_circle(name):
    """a = b: StickInEllipse is StickInCircle, collision by collision from identical states, to rounding."""
    c = DATA[name]
    ellipse = _scene(c)
    circle = jb.StickInCircle(c["a"], c["ell"], mass=c["mass"], inertia=_inertia(c))
    state = jnp.asarray(c["state0"])
    sc = _scales(c)
    for _ in range(40):
        se, te, ke = (np.asarray(v) for v in jb.collide(ellipse, state))
        sc_, tc, kc = (np.asarray(v) for v in jb.collide(circle, state))
        assert int(ke) == int(kc)
        with mp.workdps(30):
            (err,) = gen.collision_errors([te], [se], [tc], [sc_], sc)
        assert err <= 1e-13
        state = jnp.asarray(sc_)  # both continue from the same (the circle's) state


def test_equal_axes_orbits_match_stick_in_circle():
    c = DATA["circle_rotor"]
    t, s, k = _jaxbill_orbit("circle_rotor")
    orb = jb.orbit(jb.StickInCircle(2.0, 1.0), jnp.asarray(c["state0"]), c["n"])
    m = c["horizon"]
    np.testing.assert_array_equal(k[:m], np.asarray(orb.contact)[:m])
    np.testing.assert_allclose(s[:m], np.asarray(orb.state)[:m], rtol=0, atol=1e-11)


# ---------------------------------------------------------------------------
# the reference checked against what it does not use
# ---------------------------------------------------------------------------
def _reflect_numerically(a, b, ell, mass, inertia, state, k):
    """Mass-metric reflection with ``grad_q F`` from mpmath's numerical differentiation."""

    def F(x, y, al):
        px, py = x + k * ell * mpmath.cos(al), y + k * ell * mpmath.sin(al)
        return (px / a) ** 2 + (py / b) ** 2 - 1

    q = state[:3]
    G = [mpmath.diff(F, q, tuple(int(i == j) for i in range(3))) for j in range(3)]
    weights = [1 / mass, 1 / mass, 0 if (mpmath.isinf(inertia) or ell == 0) else 1 / inertia]
    along = sum(g * v for g, v in zip(G, state[3:]))
    norm2 = sum(g * g * w for g, w in zip(G, weights))
    return [v - 2 * along / norm2 * w * g for v, w, g in zip(state[3:], weights, G)]


@pytest.mark.parametrize("name", ["ratio_1.5", "mass0.3_inertia0.05", "static_ratio_2", "point_ratio_2"])
def test_reference_impulse_is_the_mass_metric_reflection(name):
    c = DATA[name]
    with mp.workdps(40):
        a, b, ell, mass, inertia = ref.params(c["a"], c["b"], c["ell"], c["mass"], c["inertia"])
        times, states, contacts = _reference(c)
        prev, t_prev = [mpf(v) for v in c["state0"]], mpf(0)
        for j in range(6):
            at_contact = ref.flow(prev, times[j] - t_prev)
            want = _reflect_numerically(a, b, ell, mass, inertia, at_contact, 1 if ell == 0 else contacts[j])
            for got, expected in zip(states[j][3:], want):
                assert abs(got - expected) < mpf("1e-20")
            prev, t_prev = states[j], times[j]


@pytest.mark.parametrize("name", ["point_ratio_2", "graze_hit_point", "point_ratio_1.5_spinning"])
def test_reference_point_conserves_the_focal_product(name):
    """The elliptic billiard's second integral, which the reference never uses."""
    c = DATA[name]
    with mp.workdps(30):
        _, states, _ = _reference(c)
        a, b, mass = mpf(c["a"]), mpf(c["b"]), mpf(c["mass"])
        start = ref.focal_product(a, b, mass, [mpf(v) for v in c["state0"]])
        scale = mass**2 * (a * a) * (states[0][3] ** 2 + states[0][4] ** 2)
        for s in states:
            assert abs(ref.focal_product(a, b, mass, s) - start) < mpf("1e-20") * scale


@pytest.mark.parametrize("name", ["fast_spin", "graze_miss_rotor", "graze_miss_rotor_b_major", "longer_than_minor"])
def test_reference_misses_no_root(name):
    """Dense float64 sampling of both ends along every reference flight: none outside the wall."""
    c = DATA[name]
    a, b, ell = c["a"], c["b"], c["ell"]
    times, states, _ = _reference(c)
    prev, t_prev = list(c["state0"]), 0.0
    for j in range(len(times)):
        dt = float(times[j]) - t_prev
        x, y, al, vx, vy, w = prev
        tt = np.linspace(0.0, dt, max(4000, int(100 * abs(w) * dt)))[1:-1]
        for k in (1, -1):
            px = x + vx * tt + k * ell * np.cos(al + w * tt)
            py = y + vy * tt + k * ell * np.sin(al + w * tt)
            assert np.all((px / a) ** 2 + (py / b) ** 2 < 1 + 1e-12), (j, k)
        prev, t_prev = [float(v) for v in states[j]], float(times[j])


def test_reference_time_reversal():
    c = DATA["ratio_1.1"]
    n = 8
    args = (c["a"], c["b"], c["ell"], c["mass"], c["inertia"])
    with mp.workdps(40):
        times, states, contacts = _reference(c)
        mid = ref.flow(states[n - 2], (times[n - 1] - times[n - 2]) / 2)
        back_t, back_s, back_k = ref.reference_orbit(*args, mid[:3] + [-v for v in mid[3:]], n - 1, dps=40)
        t_mid = (times[n - 1] + times[n - 2]) / 2
        for i in range(n - 1):
            assert abs(t_mid - back_t[i] - times[n - 2 - i]) < mpf("1e-20")
            assert back_k[i] == contacts[n - 2 - i]
