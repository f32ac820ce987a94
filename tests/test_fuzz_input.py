"""Bad input under fuzzing: malformed scenes, states and arguments.

What is required (README, "Bad input"; the docstrings of ``collide``, ``orbit``
and ``tangent_map``):

* eager calls: ``ValueError``. ``StickInCircle``, ``collide`` and ``orbit`` name
  the parameter (``R``, ``ell``, ``mass``, ``inertia``, ``state``/``omega``,
  ``n``); the other entry points (``lyapunov_spectrum``,
  ``finite_time_lyapunov``, ``find_periodic_orbit``, ``check``,
  ``section_seeds``) raise ``ValueError`` (``check`` raises its documented
  ``NotImplementedError`` for a state that is not one ``(6,)`` vector). Never a
  crash, never an error from deep inside JAX, never a result.
* inside ``jit``/``vmap`` (traced values cannot raise): NaN poisoning, the state
  and time NaN and the contact 0, for exactly the invalid rows of a batch;
  static properties (shape, dtype) can and must still raise.
* valid but extreme input: a consistent, finite collision (every moving stick
  reaches the wall of a closed billiard; energy and ``L`` conserved; the
  touching end on the wall) or, where float64 cannot represent the motion
  (``|v|^2`` or ``I omega^2`` overflowing or underflowing), a ``ValueError``,
  never a silently wrong orbit.
* never a hang. In-process calls run under a watchdog,
  ``faulthandler.dump_traceback_later(WATCHDOG_S, exit=True)``: a call stuck in
  compiled code (where Python signals such as ``signal.alarm`` cannot interrupt
  it) dumps every thread's traceback and ends the test process with an error
  instead of hanging CI. Calls that may abort the interpreter (huge counts
  reach XLA's C++ shape checks) run in subprocesses with a timeout.

Hypothesis: ``derandomize=True`` (the same examples on every run),
``deadline=None`` (a first call compiles; hangs are the watchdog's business),
few examples and no shrinking (a failing example is reported as drawn), so
that the file stays within its CI budget even while it fails.
"""

from __future__ import annotations

import contextlib
import faulthandler
import json
import math
import os
import subprocess
import sys
import textwrap
import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

import jaxbill as jb
from helpers import np_end_points, state_from_unit

WATCHDOG_S = 600  # per call; far above any compile on a loaded 2-core machine
NAN, INF = float("nan"), float("inf")
R0, ELL0 = 2.0, 1.0
GOOD = np.array([0.1, -0.2, 0.3, 0.7, 0.4, 0.5])  # valid for R = 2, ell = 1
FUZZ = settings(
    max_examples=40,
    deadline=None,
    derandomize=True,
    database=None,
    phases=[Phase.explicit, Phase.generate],  # no shrinking: a failure reports its first example, fast
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much],
)
PARAMS = ("R", "ell", "mass", "inertia")


@contextlib.contextmanager
def watchdog(seconds=WATCHDOG_S):
    faulthandler.dump_traceback_later(seconds, exit=True)
    try:
        yield
    finally:
        faulthandler.cancel_dump_traceback_later()


def outcome(fn, *args, **kwargs):
    """``("ok", result)`` or ``("raised", exception)``, under the watchdog."""
    with watchdog(), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            return "ok", fn(*args, **kwargs)
        except Exception as error:  # the type is what is asserted
            return "raised", error


def scene_of(kind):
    if kind == "rotor":
        return jb.StickInCircle(R=R0, ell=ELL0)
    if kind == "lens":
        return jb.StickInCircle(R=R0, ell=ELL0, inertia=INF)
    return jb.StickInCircle(R=R0, ell=0.0)


def valid_state(kind, u):
    return state_from_unit(R0, 0.0 if kind == "circle" else ELL0, kind, u, speed=1.0, max_spin=3.0)


# ---------------------------------------------------------------------------
# scene parameters
# ---------------------------------------------------------------------------
def _real(x):
    return isinstance(x, (int, float, np.floating, np.integer)) and not isinstance(x, bool)


def param_ok(name, value, R=None):
    """Independent oracle: is ``value`` a valid ``name`` (scalars only)?"""
    if name == "inertia" and value is None:
        return True
    if not _real(value):
        return False
    v = float(value)
    if math.isnan(v):
        return False
    if name == "inertia":
        return v > 0
    if not math.isfinite(v):
        return False
    if name == "ell":
        return 0 <= v and (R is None or v < R)
    return v > 0


BAD_VALUES = [NAN, INF, -INF, -1.0, 0.0, -1e-300, "abc", "", 1 + 1j, 2 + 0j, object(), [1.0, "x"]]


@st.composite
def scene_arguments(draw):
    """``(kwargs, bad)``: parameters where the names in ``bad`` are invalid."""
    R = draw(st.sampled_from([2.0, 0.5, 7.0]))
    kwargs = {
        "R": R,
        "ell": R * draw(st.sampled_from([0.15, 0.5, 0.999])),
        "mass": draw(st.sampled_from([1.0, 0.2, 5.0])),
        "inertia": draw(st.sampled_from([None, 0.3, 4.0, INF])),
    }
    n_bad = draw(st.integers(1, 2))
    names = draw(st.permutations(PARAMS))[:n_bad]
    for name in names:
        choices = list(BAD_VALUES)
        if name == "ell":
            choices += [R, 1.5 * R]  # ell >= R
        if name == "inertia":
            choices = [v for v in choices if not (isinstance(v, float) and v == INF)]
        kwargs[name] = draw(st.sampled_from(choices))
    bad = [n for n in PARAMS if not param_ok(n, kwargs[n], kwargs["R"] if param_ok("R", kwargs["R"]) else None)]
    return kwargs, bad


@FUZZ
@given(scene_arguments())
def test_fuzz_bad_scene_parameters_name_the_parameter(args):
    """Every invalid parameter value (NaN, inf, <= 0, ell >= R, strings,
    complex numbers, objects, ragged lists) is refused with a ValueError that
    names an invalid parameter (``param_ok`` is the oracle)."""
    kwargs, bad = args
    if not bad:
        return
    kind, result = outcome(jb.StickInCircle, **kwargs)
    assert kind == "raised", f"StickInCircle({kwargs}) accepted invalid {bad}: {result}"
    assert isinstance(result, ValueError), f"StickInCircle({kwargs}): {type(result).__name__}: {result}"
    message = str(result)
    assert any(f"{n} " in message or message.startswith(n) for n in bad), (
        f"StickInCircle({kwargs}): the error does not name the invalid parameter(s) {bad}: {message!r}"
    )


@pytest.mark.parametrize(
    "kwargs, name",
    [
        (dict(R=np.array([2.0, 3.0]), ell=np.array([1.0, 1.0, 1.0])), ("R", "ell")),
        (dict(R=2.0, ell=np.array([0.5, 1.0]), mass=np.array([1.0, 2.0, 3.0])), ("ell", "mass")),
        (dict(R=2.0, ell=1.0, inertia=np.array([1.0, 2.0, 3.0]), mass=np.array([1.0, 2.0])), ("inertia", "mass")),
    ],
)
def test_mismatched_parameter_shapes_name_the_parameters(kwargs, name):
    kind, error = outcome(jb.StickInCircle, **kwargs)
    assert kind == "raised" and isinstance(error, ValueError), (kind, error)
    assert any(n in str(error) for n in name), f"the error does not name {name}: {error}"


@pytest.mark.parametrize("kind", ["rotor", "lens", "circle"])
def test_unvmapped_batch_of_scenes_is_refused_or_right(kind):
    """A batch of scenes (parameters of shape (B,)) is meant for ``jax.vmap``;
    passed to ``collide``/``orbit`` directly it must be refused with a
    ValueError that says so (mentions the batch, the scene or vmap), or give
    each scene's own result; not an error from deep inside JAX."""
    ell = 0.0 if kind == "circle" else np.array([1.0, 1.2])
    inertia = INF if kind == "lens" else None
    scenes = jb.StickInCircle(R=np.array([2.0, 2.5]), ell=ell, inertia=inertia)
    state = GOOD * np.array([1, 1, 1, 1, 1, 0 if kind == "lens" else 1])
    singles = [
        jb.StickInCircle(R=float(scenes.R[i]), ell=float(np.atleast_1d(scenes.ell)[i]), inertia=inertia)
        for i in range(2)
    ]
    want = [np.asarray(jb.collide(single, state)[0]) for single in singles]
    for name, call in (
        ("collide", lambda: jb.collide(scenes, state)[0]),
        ("orbit", lambda: jb.orbit(scenes, state, 2).state[..., 0, :]),
    ):
        k, res = outcome(call)
        if k == "raised":
            assert isinstance(res, ValueError) and any(w in str(res) for w in ("batch", "scene", "vmap")), (
                f"{name}: {type(res).__name__}: {res}"
            )
        else:
            res = np.asarray(res)
            assert res.shape == (2, 6), f"{name}: shape {res.shape}"
            for i in range(2):
                np.testing.assert_allclose(res[i], want[i], rtol=1e-12, atol=1e-12)


# ---------------------------------------------------------------------------
# malformed states
# ---------------------------------------------------------------------------
DEFECTS = ["shape", "dtype", "nonfinite", "outside", "on_wall_outward", "lens_spin"]


@st.composite
def bad_states(draw):
    """``(scene kind, state, defect)`` with one defect (module docstring)."""
    defect = draw(st.sampled_from(DEFECTS))
    kind = "lens" if defect == "lens_spin" else draw(st.sampled_from(["rotor", "lens", "circle"]))
    u = draw(st.lists(st.floats(0.0, 1.0), min_size=6, max_size=6))
    s = valid_state(kind, u)
    if defect == "shape":
        shape = draw(st.sampled_from([(), (0,), (1,), (5,), (7,), (6, 1), (3, 2), (2, 2, 6), (1, 1, 6)]))
        return kind, np.resize(s, shape), defect
    if defect == "dtype":
        how = draw(st.sampled_from(["bool", "complex", "complex0", "object", "str", "bytes"]))
        if how == "bool":
            return kind, s.astype(bool), defect
        if how == "complex":
            return kind, s + 1j * draw(st.floats(0.01, 1.0)), defect
        if how == "complex0":
            return kind, s.astype(complex), defect
        if how == "object":
            return kind, np.array([None, *s[1:]], dtype=object), defect
        if how == "str":
            return kind, np.array([str(v) for v in s]), defect
        return kind, np.array([str(v).encode() for v in s]), defect
    if defect == "nonfinite":
        i = draw(st.integers(0, 5))
        s[i] = draw(st.sampled_from([NAN, INF, -INF]))
        return kind, s, defect
    if defect == "outside":
        # put end P1 (the centre, for the circle) at radius R (1 + excess),
        # excess in [1e-9, 1]: its gap is far below -1e-12 R^2
        excess = 10.0 ** draw(st.floats(-9.0, 0.0))
        ell = 0.0 if kind == "circle" else ELL0
        phi = draw(st.floats(0.0, 2 * math.pi))
        r = R0 * (1 + excess)
        s[0] = r * math.cos(phi) - ell * math.cos(s[2])
        s[1] = r * math.sin(phi) - ell * math.sin(s[2])
        P = np_end_points(ell, s)
        assert np.max(np.hypot(P[:, 0], P[:, 1])) >= R0 * (1 + 0.5 * excess)
        return kind, s, defect
    if defect == "on_wall_outward":
        # dyadic, exact: alpha = 0, P1 = c + ell u = (2, 0) on the wall (the
        # circle: the centre itself), its velocity along +x is vx >= 0
        ell = 0.0 if kind == "circle" else ELL0
        vx = draw(st.sampled_from([0.0, 0.25, 1.0]))
        vy = draw(st.sampled_from([0.0, 0.5, -1.0])) if vx == 0.0 else draw(st.sampled_from([0.5, -1.0]))
        w = 0.0 if kind == "lens" else draw(st.sampled_from([0.0, 0.5, -2.0]))
        if vx == 0.0 and vy == 0.0 and w == 0.0:
            vy = 0.5
        return kind, np.array([R0 - ell, 0.0, 0.0, vx, vy, w]), defect
    s[5] = draw(st.sampled_from([1e-300, -1e-12, 0.5, 1e6]))
    return "lens", s, defect


def _assert_refused(name, result, *, names=("state",), allow=()):
    kind, res = result
    assert kind == "raised", f"{name} accepted the input and returned {res}"
    assert isinstance(res, (ValueError, *allow)), f"{name}: {type(res).__name__}: {res}"
    if names and isinstance(res, ValueError):
        assert any(n in str(res) for n in names), f"{name}: the error does not name {names}: {res}"


@FUZZ
@given(bad_states())
def test_fuzz_bad_states_are_refused(case):
    """collide and orbit name the state (or ``omega`` for the lens's spin);
    lyapunov_spectrum, finite_time_lyapunov and find_periodic_orbit raise
    ValueError before any computation."""
    kind, state, defect = case
    scene = scene_of(kind)
    names = ("omega",) if defect == "lens_spin" else ("state",)
    _assert_refused("collide", outcome(jb.collide, scene, state), names=names)
    _assert_refused("orbit", outcome(jb.orbit, scene, state, 3), names=names)
    _assert_refused("lyapunov_spectrum", outcome(jb.lyapunov_spectrum, scene, state, 2), names=())
    _assert_refused("finite_time_lyapunov", outcome(jb.finite_time_lyapunov, scene, state, 2), names=())
    _assert_refused("find_periodic_orbit", outcome(jb.find_periodic_orbit, scene, state, 1), names=())


@pytest.mark.parametrize(
    "state",
    [
        np.resize(GOOD, (5,)),
        np.stack([GOOD, GOOD]),
        np.array([np.nan, *GOOD[1:]]),
        GOOD + 1j,
        np.array([1.5, *GOOD[1:]]),
    ],
    ids=["shape5", "batch", "nan", "complex", "outside"],
)
def test_check_refuses_bad_states(state):
    """``jb.check`` (diffrax): ValueError for bad values, NotImplementedError for
    anything but one ``(6,)`` state; a complex state is refused, not cast."""
    res = outcome(jb.check, scene_of("rotor"), state, 1)
    _assert_refused("check", res, names=(), allow=(NotImplementedError,))


@pytest.mark.parametrize("kind", ["rotor", "lens", "circle"])
def test_collide_with_a_batch_is_refused_or_right(kind):
    """``collide`` documents shape ``(6,)``; a ``(B, 6)`` batch must be refused with
    a ValueError naming the state, or give each row's own collision."""
    scene = scene_of(kind)
    states = np.stack(
        [valid_state(kind, [0.1, 0.3, 0.7, 0.2, 0.9, 0.5]), valid_state(kind, [0.6, 0.2, 0.4, 0.8, 0.1, 0.3])]
    )
    for batch in (states, states[:1], states[:0]):
        k, res = outcome(jb.collide, scene, batch)
        if k == "raised":
            assert isinstance(res, ValueError) and "state" in str(res), f"{type(res).__name__}: {res}"
        else:
            for i in range(batch.shape[0]):
                want = jb.collide(scene, batch[i])
                np.testing.assert_array_equal(np.asarray(res[0])[i], np.asarray(want[0]))


# ---------------------------------------------------------------------------
# counts: n, period, count
# ---------------------------------------------------------------------------
BAD_COUNTS = st.one_of(
    st.integers(-(10**6), -1),
    st.floats(allow_nan=True, allow_infinity=True),
    st.booleans(),
    st.none(),
    st.text(max_size=3),
    st.complex_numbers(max_magnitude=10),
    st.sampled_from([np.float64(3.0), np.array([3]), np.array([2, 3]), np.bool_(True), [3], (3,)]),
)


@settings(FUZZ, max_examples=30)
@given(BAD_COUNTS)
def test_fuzz_bad_counts_are_refused(n):
    """Not a (non-negative / positive) integer: ValueError (naming ``n`` for
    orbit). Booleans are not counts (``orbit(scene, s, True)`` is a bug in the
    caller)."""
    scene = scene_of("rotor")
    _assert_refused("orbit", outcome(jb.orbit, scene, GOOD, n), names=("n",))
    _assert_refused("check", outcome(jb.check, scene, GOOD, n), names=())
    _assert_refused("lyapunov_spectrum", outcome(jb.lyapunov_spectrum, scene, GOOD, n), names=())
    _assert_refused("finite_time_lyapunov", outcome(jb.finite_time_lyapunov, scene, GOOD, n), names=())
    _assert_refused("find_periodic_orbit", outcome(jb.find_periodic_orbit, scene, GOOD, n), names=())
    _assert_refused("section_seeds", outcome(jb.section_seeds, scene, n), names=())


@pytest.mark.parametrize("n", [True, False, -1, 2.0, None, "3"], ids=repr)
def test_bad_counts_explicit(n):
    """The hypothesis draw above may miss a value class; these are always run.
    ``True``/``False`` are not counts (Python's bool is an int subclass, so
    ``operator.index`` accepts it: ``orbit(scene, s, True)`` would return one
    collision)."""
    scene = scene_of("rotor")
    _assert_refused("orbit", outcome(jb.orbit, scene, GOOD, n), names=("n",))
    _assert_refused("lyapunov_spectrum", outcome(jb.lyapunov_spectrum, scene, GOOD, n), names=())
    _assert_refused("finite_time_lyapunov", outcome(jb.finite_time_lyapunov, scene, GOOD, n), names=())
    _assert_refused("find_periodic_orbit", outcome(jb.find_periodic_orbit, scene, GOOD, n), names=())
    _assert_refused("section_seeds", outcome(jb.section_seeds, scene, n), names=())


def test_valid_counts_are_accepted():
    """The other side of the fuzz: integer-like counts work (numpy integers,
    0-d integer arrays) and give the asked-for length."""
    scene = scene_of("rotor")
    for n in (0, 1, np.int64(3), np.array(3, dtype=np.int32)):
        kind, orb = outcome(jb.orbit, scene, GOOD, n)
        assert kind == "ok" and orb.t.shape == (int(n),), orb
    kind, seeds = outcome(jb.section_seeds, scene, 3)
    assert kind == "ok" and seeds.shape[1] == 6


_HUGE_SCRIPT = textwrap.dedent(
    """
    import json, sys, warnings
    import numpy as np
    import jaxbill as jb
    warnings.simplefilter("ignore")
    scene = jb.StickInCircle(R=2.0, ell=1.0)
    good = np.array([0.1, -0.2, 0.3, 0.7, 0.4, 0.5])
    calls = {
        "orbit": lambda n: jb.orbit(scene, good, n),
        "check": lambda n: jb.check(scene, good, n),
        "find_periodic_orbit": lambda n: jb.find_periodic_orbit(scene, good, n),
        "lyapunov_spectrum": lambda n: jb.lyapunov_spectrum(scene, good, n),
        "finite_time_lyapunov": lambda n: jb.finite_time_lyapunov(scene, good, n),
        "section_seeds": lambda n: jb.section_seeds(scene, n),
    }
    for item in json.loads(sys.argv[1]):
        name, n = item[0], int(item[1])
        print("START " + json.dumps(item), flush=True)
        try:
            calls[name](n)
            res = {"error": None}
        except Exception as e:
            res = {"error": type(e).__name__, "message": str(e)[:300]}
        print("RESULT " + json.dumps([item, res]), flush=True)
    """
)

# Counts no float64 orbit can hold (48 bytes a state): every call that stores
# per-collision results must refuse them or fail for want of memory; counts
# beyond int64 are refused by everyone. (lyapunov_spectrum and
# finite_time_lyapunov keep no per-collision results: for them 2**62 is a long
# run, not an error, and is not asked for.)
HUGE = [
    ("orbit", 10**15),
    ("orbit", 2**62),
    ("orbit", 2**63),
    ("orbit", 2**64),
    ("orbit", 10**30),
    ("check", 2**62),
    ("check", 2**64),
    ("find_periodic_orbit", 2**62),
    ("find_periodic_orbit", 2**64),
    ("section_seeds", 2**62),
    ("section_seeds", 2**64),
    ("lyapunov_spectrum", 2**64),
    ("finite_time_lyapunov", 2**64),
]


HUGE_TIMEOUT_S = 20  # a correct refusal takes the import (~2 s) plus microseconds


def test_huge_counts_fail_cleanly():
    """Each call must raise promptly: ValueError (naming ``n`` for orbit), or (for a count
    that fits int64) an out-of-memory error; never abort the interpreter, never
    run on. Subprocesses (an abort would end pytest itself), 20 s each; a call
    that aborts or times out is recorded and the rest are run in a fresh one."""
    remaining = [list(c) for c in HUGE]
    results = {}
    env = {**os.environ, "JAX_PLATFORMS": "cpu"}
    while remaining:
        try:
            proc = subprocess.run(
                [sys.executable, "-c", _HUGE_SCRIPT, json.dumps(remaining)],
                capture_output=True,
                text=True,
                timeout=HUGE_TIMEOUT_S,
                env=env,
            )
            out, rc, err = proc.stdout, proc.returncode, proc.stderr[-300:]
        except subprocess.TimeoutExpired as e:
            out = e.stdout.decode() if isinstance(e.stdout, bytes) else (e.stdout or "")
            rc, err = f"timeout ({HUGE_TIMEOUT_S} s)", ""
        done = [json.loads(ln[7:]) for ln in out.splitlines() if ln.startswith("RESULT ")]
        for item, res in done:
            results[tuple(item)] = res
        if len(done) < len(remaining):
            stuck = remaining[len(done)]
            results[tuple(stuck)] = {"error": f"process ended: {rc}", "message": err}
            remaining = remaining[len(done) + 1 :]
        else:
            remaining = []
    bad = {}
    for (name, n), res in results.items():
        # orbit names its argument (README); the others raise ValueError
        if res["error"] == "ValueError" and (name != "orbit" or "n " in res["message"]):
            continue
        oom = res["error"] in ("JaxRuntimeError", "XlaRuntimeError", "MemoryError") and (
            "RESOURCE_EXHAUSTED" in res["message"] or "memory" in res["message"].lower()
        )
        if oom and n < 2**63:
            continue
        bad[f"{name}(n={n})"] = res
    assert not bad, "huge counts not refused cleanly:\n" + "\n".join(f"  {k}: {v}" for k, v in bad.items())


# ---------------------------------------------------------------------------
# traced input: NaN poisoning
# ---------------------------------------------------------------------------
jit_collide = jax.jit(jb.collide)
jit_orbit = jax.jit(jb.orbit, static_argnums=2)
vmap_collide = jax.vmap(jb.collide, in_axes=(None, 0))


def _poisoned(new, dt, contact):
    return bool(
        np.all(np.isnan(np.asarray(new))) and np.all(np.isnan(np.asarray(dt))) and np.all(np.asarray(contact) == 0)
    )


@st.composite
def invalid_values(draw):
    """States of the right shape and dtype with an invalid value."""
    kind, state, defect = draw(bad_states().filter(lambda c: c[2] in ("nonfinite", "outside", "lens_spin")))
    return kind, np.asarray(state, dtype=np.float64), defect


@FUZZ
@given(invalid_values(), st.integers(0, 2))
def test_fuzz_traced_invalid_state_is_poisoned(case, row):
    """Under jit: NaN state and time, contact 0 (collide and every row of orbit);
    under vmap only the invalid row, the others exactly their eager results."""
    kind, state, _ = case
    scene = scene_of(kind)
    with watchdog():
        assert _poisoned(*jit_collide(scene, jnp.asarray(state)))
        orb = jit_orbit(scene, jnp.asarray(state), 3)
        assert _poisoned(orb.state, orb.t, orb.contact)
        good = valid_state(kind, [0.1, 0.3, 0.7, 0.2, 0.9, 0.5])
        batch = np.stack([good, good, good])
        batch[row] = state
        new, dt, contact = vmap_collide(scene, jnp.asarray(batch))
        assert _poisoned(new[row], dt[row], contact[row])
        want = jb.collide(scene, good)
        for i in {0, 1, 2} - {row}:
            np.testing.assert_allclose(np.asarray(new[i]), np.asarray(want[0]), rtol=1e-12, atol=1e-12)
            assert int(contact[i]) == int(want[2])


@jax.jit
def _collide_traced_scene(R, ell, mass, inertia, s):
    return jb.collide(jb.StickInCircle(R=R, ell=ell, mass=mass, inertia=inertia), s)


@FUZZ
@given(st.sampled_from(PARAMS), st.sampled_from([NAN, INF, -INF, -1.0, 0.0, 2.0, 3.0]))
def test_fuzz_traced_invalid_parameters_are_poisoned(name, value):
    """A scene built inside jit from traced values: an invalid one (by the
    oracle ``param_ok``; ``ell`` must also be below ``R = 2``) poisons, a valid
    one gives the eager result."""
    params = {"R": 2.0, "ell": 1.0, "mass": 1.0, "inertia": 1.0, name: value}
    valid = all(param_ok(n, params[n], 2.0) for n in PARAMS) and not math.isinf(params["inertia"])
    with watchdog():
        out = _collide_traced_scene(*(params[n] for n in PARAMS), jnp.asarray(GOOD))
    if valid:
        want = jb.collide(jb.StickInCircle(**params), GOOD)
        np.testing.assert_allclose(np.asarray(out[0]), np.asarray(want[0]), rtol=1e-14)
    else:
        assert _poisoned(*out), f"{name} = {value} inside jit was not poisoned: {out}"


@pytest.mark.parametrize("kind", ["rotor", "lens", "circle"])
@pytest.mark.parametrize("vx", [0.25, 0.0], ids=["outward", "tangent"])
def test_traced_end_on_wall_not_moving_inwards(kind, vx):
    """Refused eagerly; inside jit it must be poisoned, or be resolved as a
    collision at once after which the orbit moves on (its time advances): an
    end touching the wall tangentially must not freeze the orbit with
    zero-length flights, nor give a time of NaN with a plausible contact."""
    ell = 0.0 if kind == "circle" else ELL0
    state = jnp.asarray([R0 - ell, 0.0, 0.0, vx, 0.5, 0.0])
    scene = scene_of(kind)
    _assert_refused("collide", outcome(jb.collide, scene, state))
    with watchdog():
        orb = jit_orbit(scene, state, 3)
    if _poisoned(orb.state, orb.t, orb.contact):
        return
    t, k, s = np.asarray(orb.t), np.asarray(orb.contact), np.asarray(orb.state)
    assert np.all(np.isfinite(t)) and np.all(np.isfinite(s)), f"partly poisoned: t {t}, contact {k}"
    assert np.all(k != 0) and t[-1] > 0.0, f"the orbit is stuck on the wall: t {t}, contact {k}"


@pytest.mark.parametrize(
    "state",
    [np.resize(GOOD, 5), np.resize(GOOD, 7), GOOD + 0.5j],
    ids=["shape5", "shape7", "complex"],
)
def test_traced_static_defects_raise(state):
    """Shape and dtype are static under jit: they can raise, and must (a complex
    state is not cast silently; a wrong shape names the state)."""
    res = outcome(jit_collide, scene_of("rotor"), jnp.asarray(state))
    _assert_refused("jit(collide)", res, names=("state",), allow=(TypeError,))


@pytest.mark.parametrize("state", [np.array([NAN, *GOOD[1:]]), np.array([1.5, *GOOD[1:]])], ids=["nan", "outside"])
def test_tangent_map_of_invalid_state_is_all_nan(state):
    """``tangent_map``: "Invalid input poisons everything with NaN" (its
    docstring): the Jacobian too, not a matrix of zeros that a Lyapunov
    average would take for a contraction."""
    with watchdog():
        new, dt, contact, jac = jb.tangent_map(scene_of("rotor"), jnp.asarray(state))
    assert _poisoned(new, dt, contact)
    assert np.all(np.isnan(np.asarray(jac))), f"Jacobian of an invalid state: {np.asarray(jac)[0]}"


# ---------------------------------------------------------------------------
# valid but extreme input
# ---------------------------------------------------------------------------
@st.composite
def extreme_cases(draw):
    R = 10.0 ** draw(st.floats(-3.0, 3.0))
    kind = draw(st.sampled_from(["rotor", "rotor-scaled", "lens", "circle"]))
    ell = 0.0 if kind == "circle" else R * 10.0 ** draw(st.floats(-8.0, math.log10(1 - 1e-9)))
    mass = 10.0 ** draw(st.floats(-3.0, 3.0))
    inertia = {"rotor": None, "lens": INF, "circle": None}.get(kind)
    if kind == "rotor-scaled":
        inertia = mass * ell * ell * 10.0 ** draw(st.floats(-6.0, 6.0))
    speed = R * 10.0 ** draw(st.floats(-10.0, 10.0))
    spin = 10.0 ** draw(st.floats(-6.0, 6.0))
    u = draw(st.lists(st.floats(0.0, 1.0), min_size=6, max_size=6))
    base = "lens" if kind == "lens" else ("circle" if kind == "circle" else "rotor")
    return (R, ell, mass, inertia), state_from_unit(R, ell, base, u, speed=speed, max_spin=spin)


@FUZZ
@given(extreme_cases())
def test_fuzz_valid_extreme_input_gives_a_consistent_collision(case):
    """Speeds ``1e-10 .. 1e10 R`` per time unit, spins up to ``1e6 |v| / R``,
    ``R`` over six decades, ``ell / R`` from ``1e-8`` to ``1 - 1e-9``, masses and
    inertias over six decades: one collision, finite, with a contact, energy
    (and ``L``) conserved to ``1e-13`` of their scales, the touching end on the
    wall and no end outside by more than ``1e-12 R^2`` plus the phase rounding."""
    (R, ell, mass, inertia), s = case
    scene = jb.StickInCircle(R=R, ell=ell, mass=mass, inertia=inertia)
    kind, res = outcome(jb.collide, scene, s)
    assert kind == "ok", f"valid input refused: {res}"
    new, dt, contact = (np.asarray(v) for v in res)
    assert np.all(np.isfinite(new)) and np.isfinite(dt) and dt > 0.0, (new, dt)
    assert int(contact) in (1, -1, 2), contact
    E0, E1 = float(jb.energy(scene, s)), float(jb.energy(scene, new))
    assert abs(E1 - E0) <= 1e-13 * E0
    if scene.kind == "rotor":
        I = float(scene.inertia)
        scale = R * math.sqrt(2 * mass * E0) + math.sqrt(2 * I * E0)
        dL = float(jb.angular_momentum(scene, new) - jb.angular_momentum(scene, s))
        assert abs(dL) <= 1e-13 * scale
    P = np_end_points(ell, new).astype(np.longdouble)
    gaps = np.longdouble(R) ** 2 - np.sum(P * P, axis=-1)
    phase = 8 * 2.0**-52 * (math.pi + abs(s[5] * float(dt)))
    tol = 1e-12 * R * R + 2 * R * ell * phase
    assert float(np.min(gaps)) >= -tol
    touching = (0,) if (ell == 0 or int(contact) == 1) else (1,) if int(contact) == -1 else (0, 1)
    assert all(abs(float(gaps[i])) <= tol for i in touching), (gaps, tol)


@pytest.mark.parametrize("kind", ["rotor", "lens", "circle"])
@pytest.mark.parametrize("speed", [1e-170, 1e160, 1e200])
def test_speed_beyond_float64_squares_is_refused_or_right(kind, speed):
    """``|v|^2`` underflows (1e-170) or overflows (1e160, 1e200) in float64. The
    centre starts at the origin moving along x with the stick along y, so the
    first contact is at ``t = sqrt(R^2 - ell^2) / |v|`` (both ends at once for a
    non-spinning stick; the circle: ``R / |v|``), finite in every case. Either
    that, or a ValueError; never "no collision" (``dt = inf``) or NaN."""
    ell = 0.0 if kind == "circle" else ELL0
    state = np.array([0.0, 0.0, math.pi / 2, speed, 0.0, 0.0])
    k, res = outcome(jb.collide, scene_of(kind), state)
    if k == "raised":
        assert isinstance(res, ValueError), f"{type(res).__name__}: {res}"
        return
    new, dt, contact = (np.asarray(v) for v in res)
    exact = math.sqrt(R0 * R0 - ell * ell) / speed
    assert int(contact) != 0 and np.isfinite(dt), f"a moving stick never reaches the wall: dt {dt}, contact {contact}"
    assert abs(float(dt) - exact) <= 1e-12 * exact
    assert np.all(np.isfinite(new)) and new[3] < 0.0


@pytest.mark.parametrize("omega", [1e155, 1e300])
def test_spin_energy_overflow_is_refused_or_conserved(omega):
    """``I omega^2`` overflows: refuse (ValueError), or conserve the energy."""
    state = np.array([0.0, 0.0, 0.0, 1.0, 0.0, omega])
    scene = scene_of("rotor")
    k, res = outcome(jb.collide, scene, state)
    if k == "raised":
        assert isinstance(res, ValueError), f"{type(res).__name__}: {res}"
        return
    E0, E1 = float(jb.energy(scene, state)), float(jb.energy(scene, res[0]))
    assert math.isfinite(E0) and abs(E1 - E0) <= 1e-13 * E0, f"energy {E0} -> {E1}"


# ---------------------------------------------------------------------------
# section functions and invariants: pure functions of (..., 6) states
# ---------------------------------------------------------------------------
SECTION_FUNCTIONS = {
    "paper_section": (jb.paper_section, "rotor"),
    "reduced_section": (jb.reduced_section, "rotor"),
    "birkhoff_section": (jb.birkhoff_section, "lens"),
    "energy": (jb.energy, "rotor"),
    "angular_momentum": (jb.angular_momentum, "rotor"),
    "end_points": (jb.end_points, "rotor"),
}


@settings(FUZZ, max_examples=15)
@given(
    st.sampled_from(list(SECTION_FUNCTIONS)),
    st.lists(st.integers(1, 3), max_size=2),
    st.integers(0, 12).filter(lambda k: k != 6),
)
def test_fuzz_section_functions_reject_wrong_last_axis(name, lead, last):
    """A state is ``(..., 6)``; any other last axis is refused (JAX clamps
    out-of-range indices, so without a check ``state[..., 5]`` of a 3-vector
    silently reads ``state[..., 2]``). The shape is static: under ``jit`` too."""
    fn, kind = SECTION_FUNCTIONS[name]
    states = np.resize(GOOD, (*lead, last))
    scene = scene_of(kind)
    _assert_refused(name, outcome(fn, scene, states), names=(), allow=(TypeError,))
    _assert_refused(f"jit({name})", outcome(jax.jit(fn), scene, jnp.asarray(states)), names=(), allow=(TypeError,))


@pytest.mark.parametrize("name", list(SECTION_FUNCTIONS))
@pytest.mark.parametrize("how", ["str", "object"])
def test_section_functions_reject_non_numeric_states(name, how):
    fn, kind = SECTION_FUNCTIONS[name]
    state = {"str": np.array([str(v) for v in GOOD]), "object": np.array([None, *GOOD[1:]], dtype=object)}[how]
    _assert_refused(name, outcome(fn, scene_of(kind), state), names=(), allow=(TypeError,))


@pytest.mark.parametrize("name", list(SECTION_FUNCTIONS))
def test_section_functions_propagate_nan(name):
    """NaN in, NaN out (for the affected row only): a pure function has no
    other way to say so, and must not return a plausible number."""
    fn, kind = SECTION_FUNCTIONS[name]
    states = np.stack([GOOD, GOOD])
    states[1, :] = NAN
    if kind == "lens":
        states[0, 5] = 0.0
    with watchdog():
        out = np.asarray(fn(scene_of(kind), jnp.asarray(states)))
    assert np.all(np.isfinite(out[0]))
    assert np.all(np.isnan(out[1])), out[1]
