"""The engine's trigonometry in arithmetic that vectorises: ``cos`` and ``sin`` of one angle together,
and the remainder by ``2 pi``.

XLA:CPU evaluates a float64 ``cos``, ``sin`` or remainder (``fmod``) as a
library call per value, lane by lane, even in a vectorised loop: in a
lockstep batch of spinning sticks the cosine and sine of each root step cost
as much as the rest of the step. Here both come from one argument reduction
and two polynomials, elementwise arithmetic that runs four lanes to an
instruction and lowers unchanged in a Pallas kernel (the measurements, before
and after: ``benchmarks/HISTORY.md``).

The cosine and sine (``tests/test_trig.py``, against 60-digit mpmath): within ``1.11 *
2**-53`` absolute of the true values for ``|phi| < 1e4`` (about one ulp of a
value near 1; the library functions' half an ulp, ``0.5 * 2**-53``), within
``1.27 * 2**-53`` up to ``|phi| = 1e9``. Past ``|phi| ~ 3e9`` the reduction is
no longer exact and the error grows like ``ulp(phi)``, the rounding that
``phi`` itself carries. The remainder is exact, ``jnp.remainder``'s to the
bit, below ``2**26`` turns.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp

# pi/2 as a sum of four doubles, the first three of 22 significant bits each, so
# that k * part is exact for |k| < 2**31 (Cody and Waite's reduction); together
# they hold pi/2 to about 2**-120 (checked against mpmath in tests/test_trig.py).
PI_OVER_2_PARTS = (
    float.fromhex("0x1.921fb00000000p+0"),
    float.fromhex("0x1.5110b00000000p-22"),
    float.fromhex("0x1.1846980000000p-44"),
    float.fromhex("0x1.3198a2e037073p-69"),
)

# Taylor coefficients on |r| <= pi/4: the first omitted terms, r^19/19! and
# r^18/18!, are below 1e-19 and 2e-18 there.
_SIN_COEFFICIENTS = tuple((-1) ** i / math.factorial(2 * i + 1) for i in range(1, 9))  # r^3 .. r^17
_COS_COEFFICIENTS = tuple((-1) ** i / math.factorial(2 * i) for i in range(2, 9))  # r^4 .. r^16


def _estrin(coefficients: tuple, z):
    """``sum_i coefficients[i] z^i`` by Estrin's scheme: pairs, then pairs of pairs. Its chain of
    dependent operations is half Horner's, and one orbit is bound by that chain's latency."""
    terms, power = list(coefficients), z
    while len(terms) > 1:
        paired = [terms[i] + terms[i + 1] * power for i in range(0, len(terms) - 1, 2)]
        terms = paired + terms[len(paired) * 2 :]
        power = power * power
    return terms[0]


@jax.custom_jvp
def cos_sin_polynomial(phi):
    """``(cos phi, sin phi)`` of a float64 array, elementwise (NaN for a non-finite ``phi``)."""
    quarter_turns = jnp.floor(phi * (2.0 / math.pi) + 0.5)
    r = phi
    for part in PI_OVER_2_PARTS:
        r = r - quarter_turns * part
    z = r * r
    sin_r = r + r * (z * _estrin(_SIN_COEFFICIENTS, z))
    # 1 - z/2 with its rounding error carried into the small terms.
    half_z = 0.5 * z
    w = 1.0 - half_z
    cos_r = w + (((1.0 - w) - half_z) + (z * z) * _estrin(_COS_COEFFICIENTS, z))
    quadrant = quarter_turns - 4.0 * jnp.floor(quarter_turns * 0.25)
    odd = (quadrant == 1.0) | (quadrant == 3.0)
    cos_phi = jnp.where(odd, sin_r, cos_r)
    sin_phi = jnp.where(odd, cos_r, sin_r)
    cos_phi = jnp.where((quadrant == 1.0) | (quadrant == 2.0), -cos_phi, cos_phi)
    sin_phi = jnp.where((quadrant == 2.0) | (quadrant == 3.0), -sin_phi, sin_phi)
    return cos_phi, sin_phi


@cos_sin_polynomial.defjvp
def _cos_sin_polynomial_jvp(primals, tangents):
    # The derivatives are the values themselves: no differentiation through the
    # reduction and the polynomials.
    (phi,), (phi_dot,) = primals, tangents
    cos_phi, sin_phi = cos_sin_polynomial(phi)
    return (cos_phi, sin_phi), (-sin_phi * phi_dot, cos_phi * phi_dot)


# 2 pi (the double 2 * math.pi) as HIGH + LOW exactly: HIGH of 26 significant bits,
# LOW of 25, so that k * HIGH and k * LOW are exact for k <= 2**26.
TWO_PI = 2.0 * math.pi
_TWO_PI_HIGH = float.fromhex("0x1.921fb50000000p+2")
_TWO_PI_LOW = float.fromhex("0x1.110b460000000p-24")
# Below this |x| (2**26 turns) remainder_two_pi is exact.
EXACT_REMAINDER_LIMIT = 2.0**26 * TWO_PI


def remainder_two_pi(x):
    """``jnp.remainder(x, TWO_PI)`` to the bit for ``|x| < EXACT_REMAINDER_LIMIT``, in arithmetic that vectorises.

    XLA:CPU calls ``fmod`` value by value, a large share of the circle
    billiard's collision, which is a few dozen flops. An inexact wrap
    (``x - 2 pi floor(x / 2 pi)``) vectorises, and so runs faster, but is not
    ``jnp.remainder`` to the bit; this exact one vectorises too and keeps most
    of that gain (the circle's batch, measured before and after:
    ``benchmarks/HISTORY.md``).

    The remainder of ``|x|`` by ``TWO_PI`` is exact here as in ``fmod``:
    ``turns * HIGH`` and ``turns * LOW`` are exact products; ``|x| - turns *
    HIGH`` is a difference of multiples of ``ulp(|x|)`` no larger than
    ``|x|``, so exact too; and the last subtraction's exact value is the
    remainder itself, a double, which rounding returns unchanged. A quotient
    rounded up to the next integer leaves the remainder minus ``TWO_PI`` (a
    small negative double), put back exactly; a correctly rounded quotient is
    never rounded below an integer. Then, as ``jnp.remainder``, the sign of
    ``x`` and one ``TWO_PI`` added to a negative result.
    """
    size = jnp.abs(x)
    turns = jnp.floor(size / TWO_PI)
    rest = (size - turns * _TWO_PI_HIGH) - turns * _TWO_PI_LOW
    rest = jnp.where(rest < 0.0, rest + TWO_PI, rest)
    # Under one turn the remainder is |x| itself, passed on unrounded
    # (XLA:CPU flushes subnormal operands of arithmetic to zero; fmod keeps them).
    rest = jnp.where(turns == 0.0, size, rest)
    truncated = jnp.copysign(rest, x)
    return jnp.where(truncated < 0.0, truncated + TWO_PI, truncated)
