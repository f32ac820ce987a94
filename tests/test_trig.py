"""The engine's cosine and sine (jaxbill._engine.trig) against mpmath at 60 digits."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from mpmath import mp, mpf

from jaxbill._engine.trig import PI_OVER_2_PARTS, cos_sin_polynomial

UNIT = 2.0**-53  # half an ulp of 1: the library functions' error is about this


def _worst_errors(phis: np.ndarray) -> tuple[float, float]:
    cos, sin = (np.asarray(a) for a in jax.jit(cos_sin_polynomial)(jnp.asarray(phis)))
    with mp.workdps(60):
        cos_error = max(abs(float(mpf(float(c)) - mp.cos(mpf(float(p))))) for p, c in zip(phis, cos, strict=True))
        sin_error = max(abs(float(mpf(float(s)) - mp.sin(mpf(float(p))))) for p, s in zip(phis, sin, strict=True))
    return cos_error, sin_error


def _near_quarter_turns(count: int) -> np.ndarray:
    """The doubles next to k pi/2, where the reduction cancels most."""
    centres = np.arange(1, count + 1) * (np.pi / 2)
    return np.concatenate([centres, np.nextafter(centres, 0.0), np.nextafter(centres, np.inf), -centres])


@pytest.mark.parametrize(
    ("name", "bound"),
    [("one turn", 1.25), ("ten thousand", 1.25), ("a billion", 1.5), ("quarter turns", 1.25), ("tiny", 1.25)],
)
def test_within_about_one_ulp_of_the_true_values(name, bound):
    """Absolute error at most ``bound * 2**-53`` (the library's is ``0.5 * 2**-53``) where a stick's
    angle lives (a turn, or many in a long flight of a fast spin), and next to the quarter turns."""
    rng = np.random.default_rng(7)
    phis = {
        "one turn": rng.uniform(-4.0, 4.0, 3000),
        "ten thousand": rng.uniform(-1e4, 1e4, 2000),
        "a billion": rng.uniform(-1e9, 1e9, 1000),
        "quarter turns": _near_quarter_turns(300),
        "tiny": 10.0 ** rng.uniform(-300, -1, 500) * rng.choice([-1.0, 1.0], 500),
    }[name]
    cos_error, sin_error = _worst_errors(phis)
    assert cos_error <= bound * UNIT
    assert sin_error <= bound * UNIT


def test_exact_values_and_symmetries():
    """cos 0 = 1 and sin 0 = 0 exactly; cos is even and sin odd to the bit; non-finite angles give NaN."""
    cos, sin = cos_sin_polynomial(jnp.asarray([0.0, -0.0]))
    np.testing.assert_array_equal(np.asarray(cos), [1.0, 1.0])
    np.testing.assert_array_equal(np.asarray(sin), [0.0, -0.0])
    phis = np.random.default_rng(3).uniform(0.0, 1e3, 1000)
    cos_plus, sin_plus = cos_sin_polynomial(jnp.asarray(phis))
    cos_minus, sin_minus = cos_sin_polynomial(jnp.asarray(-phis))
    np.testing.assert_array_equal(np.asarray(cos_minus), np.asarray(cos_plus))
    np.testing.assert_array_equal(np.asarray(sin_minus), -np.asarray(sin_plus))
    cos, sin = cos_sin_polynomial(jnp.asarray([np.inf, -np.inf, np.nan]))
    assert np.all(np.isnan(np.asarray(cos))) and np.all(np.isnan(np.asarray(sin)))


def test_derivatives_are_minus_sine_and_cosine():
    """Forward and reverse mode give ``(-sin, cos)`` times the tangent, from the function's own values."""
    phi = jnp.asarray(2.345)
    (cos, sin), (cos_dot, sin_dot) = jax.jvp(cos_sin_polynomial, (phi,), (jnp.asarray(3.0),))
    assert float(cos_dot) == -3.0 * float(sin) and float(sin_dot) == 3.0 * float(cos)
    grad = jax.grad(lambda p: cos_sin_polynomial(p)[1])(phi)
    np.testing.assert_allclose(float(grad), math.cos(2.345), rtol=0, atol=2 * UNIT)


def test_the_parts_of_a_quarter_turn():
    """The reduction's constants: the first three hold at most 22 significant bits (so ``k * part`` is
    exact for ``|k| < 2**31``) and the four sum to pi/2 within ``2**-118``."""
    for part in PI_OVER_2_PARTS[:3]:
        mantissa, _ = math.frexp(part)
        assert (mantissa * 2**22).is_integer()
    with mp.workdps(60):
        assert abs(sum(mpf(p) for p in PI_OVER_2_PARTS) - mp.pi / 2) < mpf(2) ** -118


def _same_doubles(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return bool(np.all(((a == b) & (np.signbit(a) == np.signbit(b))) | (np.isnan(a) & np.isnan(b))))


def test_remainder_by_two_pi_is_the_librarys_to_the_bit():
    """``remainder_two_pi`` against ``jnp.remainder`` (a library ``fmod``), bit for bit: random angles up to
    the limit, the doubles at and next to whole turns (where the quotient rounds to an integer), signed
    zeros, subnormals and non-finite values."""
    from jaxbill._engine.trig import EXACT_REMAINDER_LIMIT, TWO_PI, remainder_two_pi

    rng = np.random.default_rng(11)
    turns = np.arange(-(2.0**26), 2.0**26, 6007.0) * TWO_PI
    x = np.concatenate(
        [
            rng.uniform(-10.0, 10.0, 20000),
            rng.uniform(-EXACT_REMAINDER_LIMIT, EXACT_REMAINDER_LIMIT, 20000),
            10.0 ** rng.uniform(-320.0, 8.6, 20000) * rng.choice([-1.0, 1.0], 20000),
            turns,
            np.nextafter(turns, np.inf),
            np.nextafter(turns, -np.inf),
            [0.0, -0.0, 5e-324, -5e-324, TWO_PI, -TWO_PI, np.pi, -np.pi, np.inf, -np.inf, np.nan],
            [np.nextafter(EXACT_REMAINDER_LIMIT, 0.0), -np.nextafter(EXACT_REMAINDER_LIMIT, 0.0)],
        ]
    )
    ours = jax.jit(remainder_two_pi)(jnp.asarray(x))
    library = jax.jit(lambda a: jnp.remainder(a, TWO_PI))(jnp.asarray(x))
    assert _same_doubles(ours, library)


def test_a_lockstep_batch_wraps_angles_as_the_library_does():
    """``wrapped_angle`` in a lockstep batch (its own arithmetic, and the library's past the limit) gives
    ``jnp.remainder(phi + pi, 2 pi) - pi`` to the bit, beyond the limit and for NaN too."""
    from jaxbill._engine.step import vmapped_over_lanes, wrapped_angle
    from jaxbill._engine.trig import EXACT_REMAINDER_LIMIT

    rng = np.random.default_rng(12)
    for phis in (rng.uniform(-1e3, 1e3, 64), np.array([1.0, -3.0, 3.0 * EXACT_REMAINDER_LIMIT, np.nan])):
        wrapped = jax.jit(vmapped_over_lanes(wrapped_angle, (0,)))(jnp.asarray(phis))
        expected = jnp.remainder(jnp.asarray(phis) + jnp.pi, 2.0 * jnp.pi) - jnp.pi
        assert _same_doubles(wrapped, expected)
