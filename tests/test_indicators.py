"""Fast chaos indicators (jaxbill._analysis.indicators): FLI and MEGNO against their known behaviour.

References, independent of the code:
* analytic growth laws fed to the accumulator: linear growth gives
  ``Y = 2 - (2a/(b t)) log(1 + b t / a)``, exponential growth ``Y = lambda t``
  and ``<Y> = lambda t / 2`` exactly;
* a stick that never turns between flat walls bounces in one dimension: its
  flow tangent vector from ``(dz, dvz) = (0, 1)`` is ``(+-t, +-1)``, so
  ``FLI = log(1 + t^2) / 2`` and ``Y = 2 - 2 arctan(t) / t`` exactly, while
  its collision map is an isometry (``FLI = <Y> = 0``);
* the integrable circle and ellipse billiards (a point particle): ``FLI``
  grows like ``log n``, ``<Y> -> 2``;
* chaotic orbits: ``FLI ~ lambda n`` and ``<Y> ~ lambda n / 2`` with
  ``lambda`` measured by ``jb.finite_time_lyapunov`` on the same orbit.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import quad

import jaxbill as jb
from jaxbill._analysis.indicators import _accumulate, _mean_megno

N = 2000
LOG4 = math.log(4.0)

ROTOR = jb.StickInCircle(R=2.0, ell=1.0)
ROTOR_STATE = [0.1, -0.2, 0.3, 0.6, 0.5, 0.7]
CIRCLE = jb.StickInCircle(R=2.0, ell=0.0)
CIRCLE_STATE = [0.3, -0.2, 0.0, 0.6, 0.5, 0.0]
LENS = jb.StickInCircle(R=2.0, ell=1.5, inertia=float("inf"))
# In the island about the stable orbit bouncing along the lens's short axis (x
# for alpha = 0), away from its centre; and a start in the chaotic sea.
LENS_REGULAR = [0.105, 0.492, 0.0, 0.992291, -0.1239297, 0.0]
LENS_CHAOTIC = [-0.3985, 0.2377, 0.0, 0.0967530, 0.9953084, 0.0]
ELLIPSE_POINT = jb.StickInEllipse(a=2.0, b=1.2, ell=0.0)
ELLIPSE_POINT_STATE = [-1.44, -0.77, 0.0, 0.912196, -0.409754, 0.0]
ELLIPSE_ROTOR = jb.StickInEllipse(a=2.0, b=1.2, ell=0.6)
ELLIPSE_ROTOR_STATE = [0.242, -0.358, -0.111, 0.818, -0.569, -0.082]
WALLS_STATIC = jb.StickBetweenWalls2D(h=3.0, ell=1.0, inertia=float("inf"))
WALLS_STATIC_STATE = [0.0, 1.2, 0.7, 0.3, 0.8, 0.0]
WALLS_ROTOR = jb.StickBetweenWalls2D(h=3.0, ell=1.0)
WALLS_ROTOR_STATE = [0.0, 0.8166, 0.7190, 0.8087, 0.5846, -0.0651]
# In space the dynamical frame moves with the state (jaxbill.dynamical_frame).
WALLS_3D = jb.StickBetweenWalls3D(h=3.0, ell=1.0)
_U = np.array([math.sin(0.7) * math.cos(0.3), math.sin(0.7) * math.sin(0.3), math.cos(0.7)])
WALLS_3D_STATE = [0.0, 0.0, 1.2, *_U, 0.2, -0.1, 0.6, *np.cross(_U, [0.3, -0.5, 0.4])]


def _accumulated(log_norms, taus):
    """Y and <Y> from samples L_k at times tau_k, through the library's per-collision update."""
    zero = jnp.zeros(())
    carry = (zero, zero, zero, zero, zero, zero)
    previous = 0.0
    for log_norm, tau in zip(log_norms, taus):
        carry = _accumulate(carry, log_norm - previous, jnp.asarray(tau), megno=True)
        previous = log_norm
    _, fli, tau, _, y, area = carry
    return float(fli), float(y), float(_mean_megno(area, tau))


def test_megno_discretisation_on_analytic_growth():
    rng = np.random.default_rng(1)
    taus = np.cumsum(rng.uniform(0.5, 1.5, 3000))  # irregular flight times
    # Exponential growth: the trapezoid rules are exact for L linear in tau.
    lam = 0.3
    fli, y, mean_y = _accumulated(lam * taus, taus)
    assert fli == pytest.approx(lam * taus[-1], rel=1e-12)
    assert y == pytest.approx(lam * taus[-1], rel=1e-12)
    assert mean_y == pytest.approx(lam * taus[-1] / 2, rel=1e-12)
    # Linear growth |w| = a + b tau from |w(0)| = a = 1: Y = 2 - (2/(b t)) log(1 + b t).
    b = 0.7
    fli, y, mean_y = _accumulated(np.log1p(b * taus), taus)
    t = taus[-1]
    exact_y = 2 - 2 / (b * t) * math.log1p(b * t)
    exact_mean = quad(lambda s: 2 - 2 / (b * s) * math.log1p(b * s) if s > 0 else 0.0, 0, t, limit=400)[0] / t
    assert fli == pytest.approx(math.log1p(b * t), rel=1e-12)
    # Steps of ~1 where L'' ~ 1/s^2: the trapezoid error in Y and <Y> is O(log t / t) ~ 3e-3.
    assert abs(y - exact_y) < 3e-3 and abs(mean_y - exact_mean) < 3e-3
    # Its approach to 2: -Li2(-x) = log(x)^2 / 2 + pi^2 / 6 + O(1/x) gives 2 - (log(x)^2 + pi^2/3) / x, x = b t.
    x = b * t
    assert abs((2 - mean_y) - (math.log(x) ** 2 + math.pi**2 / 3) / x) < 3e-3


def test_static_stick_between_walls_matches_the_one_dimensional_bounce():
    s = jnp.asarray(WALLS_STATIC_STATE)
    f = jb.fli(WALLS_STATIC, s, N, per="time", n_history=4)
    m = jb.megno(WALLS_STATIC, s, N, per="time", n_history=4)
    t = float(f.time)
    assert float(f.value) == pytest.approx(0.5 * math.log1p(t * t), rel=1e-10)
    np.testing.assert_allclose(np.asarray(f.history), 0.5 * np.log1p(np.asarray(f.times) ** 2), rtol=1e-10)
    exact_y = 2 - 2 * math.atan(t) / t
    exact_mean = 2 - 2 / t * quad(lambda s: math.atan(s) / s if s > 0 else 1.0, 0, t, limit=400)[0]
    # Flights of ~1.8: trapezoid error in Y ~ h^2/(6 t) and in <Y> ~ h^2 log(t) / (6 t), below 2e-3 here.
    assert abs(float(m.instantaneous) - exact_y) < 2e-3
    assert abs(float(m.value) - exact_mean) < 2e-3
    # The collision map keeps z on the walls and flips vz: an isometry of (dz, dvz).
    f = jb.fli(WALLS_STATIC, s, N, n_history=4)
    m = jb.megno(WALLS_STATIC, s, N, n_history=4)
    assert abs(float(f.value)) < 1e-12 and abs(float(m.value)) < 1e-12


@pytest.mark.parametrize("per", ["collision", "time"])
def test_circle_billiard_is_regular(per):
    s = jnp.asarray([CIRCLE_STATE])
    f = jb.fli(CIRCLE, s, N, per=per, n_history=4)
    m = jb.megno(CIRCLE, s, N, per=per, n_history=4)
    # Checkpoints at n/4 ... n: linear growth adds log 4 to the FLI (a chaotic orbit
    # would add ~ 3 lambda n / 4, a bounded vector 0).
    assert abs(float(f.history[0, -1] - f.history[0, 0]) - LOG4) < 0.1
    assert abs(float(m.value[0]) - 2.0) < 0.05
    assert jb.finite_time_lyapunov(CIRCLE, s, N).per_collision[0] < jb.chaos_threshold(N)


REGULAR = {
    "lens": (LENS, LENS_REGULAR, 0.15, 0.15),
    "ellipse point": (ELLIPSE_POINT, ELLIPSE_POINT_STATE, 0.1, 0.05),
}


@pytest.mark.parametrize("name", REGULAR)
def test_regular_orbits_of_the_lens_and_the_ellipse(name):
    """FLI grows like log n and <Y> tends to 2.

    The integrable ellipse converges as fast as the circle. The lens orbit
    winds about a stable periodic orbit, where the twist is weak (|w| = a + b n
    with a/b large), so <Y> approaches 2 from below more slowly: the wider tolerance.
    """
    scene, state, fli_tolerance, megno_tolerance = REGULAR[name]
    s = jnp.asarray([state])
    assert jb.finite_time_lyapunov(scene, s, N).per_collision[0] < jb.chaos_threshold(N)
    f = jb.fli(scene, s, N, n_history=4)
    m = jb.megno(scene, s, N, n_history=4)
    assert abs(float(f.history[0, -1] - f.history[0, 0]) - LOG4) < fli_tolerance
    assert abs(float(m.value[0]) - 2.0) < megno_tolerance


CHAOTIC = {
    "rotor": (ROTOR, ROTOR_STATE),
    "lens": (LENS, LENS_CHAOTIC),
    "ellipse": (ELLIPSE_ROTOR, ELLIPSE_ROTOR_STATE),
    "walls": (WALLS_ROTOR, WALLS_ROTOR_STATE),
    "walls 3D": (WALLS_3D, WALLS_3D_STATE),
}


@pytest.mark.parametrize("name,per", [(name, "collision") for name in CHAOTIC] + [("rotor", "time")])
def test_chaotic_orbits_grow_at_the_lyapunov_rate(name, per):
    """FLI ~ lambda tau and <Y> ~ lambda tau / 2, lambda from finite_time_lyapunov on the same orbit.

    The FLI's vector and finite_time_lyapunov's (another start, the flow's
    maps) align with the unstable direction within a few collisions and then
    stretch alike: they differ by O(1) in log, 3% of lambda n here. <Y> is a
    weighted time average of the stretching rate (2 <Y> / tau =
    int L'(s) w(s) ds with w(s) = 4 s log(tau/s) / tau^2), lambda an
    unweighted one: on one orbit of a few thousand collisions they differ by
    the fluctuations of the local rate, a few percent: 10% tolerance.
    """
    scene, state = CHAOTIC[name]
    s = jnp.asarray([state])
    ftle = jb.finite_time_lyapunov(scene, s, N)
    assert ftle.per_collision[0] > 5 * jb.chaos_threshold(N)
    f = jb.fli(scene, s, N, per=per, n_history=4)
    m = jb.megno(scene, s, N, per=per, n_history=4)
    lam, tau = (float(ftle.per_collision[0]), N) if per == "collision" else (float(ftle.per_time[0]), float(f.time[0]))
    assert float(f.value[0]) == pytest.approx(lam * tau, rel=0.03)
    assert 2 * float(m.value[0]) / tau == pytest.approx(lam, rel=0.10)
    # The history keeps the running maximum: never decreasing, ending at the value.
    assert np.all(np.diff(np.asarray(f.history[0])) >= 0) and float(f.history[0, -1]) == float(f.value[0])


def test_vmapped_and_batched_results_equal_single_ones():
    # Few collisions: rounding differences between programs grow like e^(lambda n) on chaotic orbits.
    n = 30
    states = jnp.asarray([LENS_REGULAR, LENS_CHAOTIC, [0.1, -0.3, 0.0, 0.6, 0.8, 0.0]])
    single = [jb.fli(LENS, s, n) for s in states]
    single_megno = [jb.megno(LENS, s, n) for s in states]
    batched = jb.fli(LENS, states, n)
    vmapped = jax.vmap(lambda s: jb.fli(LENS, s, n))(states)
    vmapped_megno = jax.vmap(lambda s: jb.megno(LENS, s, n))(states)
    assert batched.value.shape == (3,) and batched.history.shape == (3, n) and batched.collisions.shape == (n,)
    for i, one in enumerate(single):
        assert one.value.shape == () and one.history.shape == (n,)
        for result in (batched, vmapped):
            np.testing.assert_allclose(float(result.value[i]), float(one.value), rtol=1e-9)
            np.testing.assert_allclose(np.asarray(result.history[i]), np.asarray(one.history), rtol=1e-9)
        np.testing.assert_allclose(float(vmapped_megno.value[i]), float(single_megno[i].value), rtol=1e-9)
    # A user-given tangent vector per state. The flow's maps carry the flow direction to
    # itself (|f| = |v| for the lens: FLI = 0), while the chaotic orbit stretches any other.
    flow = jax.vmap(LENS.phase_velocity)(states)
    along_flow = jb.fli(LENS, states, n, tangent0=flow, per="time", n_history=4)
    np.testing.assert_allclose(np.asarray(along_flow.value), 0.0, atol=1e-9)
    across = jb.fli(LENS, states, n, tangent0=flow[:, [1, 0, 2, 4, 3, 5]], per="time", n_history=4)
    assert float(across.value[1]) > 1.0


def test_fli_map_has_the_grid_shape_and_separates_regular_from_chaotic():
    n = 300
    grid = np.array(
        [
            [LENS_REGULAR, LENS_CHAOTIC, [0.0, 0.0, 0.0, 1.0, 0.0, 0.0]],
            [LENS_CHAOTIC, [5.0, 0.0, 0.0, 1.0, 0.0, 0.0], [np.nan] * 6],
        ]
    )
    fli_map = jb.fli_map(LENS, grid, n, chunk=3)
    assert fli_map.shape == (2, 3)
    # Outside the lens and NaN starts: blank pixels, not an error.
    assert np.isnan(fli_map[1, 1]) and np.isnan(fli_map[1, 2])
    direct = jb.fli(LENS, grid[0], n, n_history=1).value
    np.testing.assert_allclose(fli_map[0], np.asarray(direct), rtol=1e-6)
    assert fli_map[0, 1] > 5 * fli_map[0, 0]  # chaotic ~ lambda n = 40, regular ~ log n = 5

    from matplotlib.figure import Figure

    from jaxbill.plotting import plot_fli_map

    ax = Figure().add_subplot()
    assert plot_fli_map(ax, fli_map, (0, 3, 0, 2), xlabel="s", ylabel="p") is ax
    assert ax.get_xlabel() == "s" and ax.get_ylabel() == "p"
    shown = ax.images[0].get_array()
    assert shown.mask[1, 1] and float(shown[0, 1]) == fli_map[0, 1]
    with pytest.raises(ValueError, match="values"):
        plot_fli_map(ax, fli_map[0], (0, 3, 0, 2), xlabel="s", ylabel="p")


@pytest.mark.parametrize("bad_n", [0, -3, 2.5, True, "10", None])
def test_bad_counts_name_the_parameter(bad_n):
    for function in (jb.fli, jb.megno, jb.fli_map):
        with pytest.raises(ValueError, match="^n must"):
            function(ROTOR, jnp.asarray(ROTOR_STATE), bad_n)
    with pytest.raises(ValueError, match="^n_history must"):
        jb.fli(ROTOR, jnp.asarray(ROTOR_STATE), 10, n_history=0)
    with pytest.raises(ValueError, match="^chunk must"):
        jb.fli_map(ROTOR, jnp.asarray(ROTOR_STATE), 10, chunk=0)


def test_bad_shapes_and_options_name_the_parameter():
    state = jnp.asarray(ROTOR_STATE)
    with pytest.raises(ValueError, match="^state"):
        jb.fli(ROTOR, state[:5], 10)
    with pytest.raises(ValueError, match="^state"):
        jb.megno(ROTOR, jnp.zeros((2, 2, 6)), 10)
    with pytest.raises(ValueError, match="^states_grid"):
        jb.fli_map(ROTOR, jnp.zeros((3, 4, 5)), 10)
    with pytest.raises(ValueError, match="^per must"):
        jb.fli(ROTOR, state, 10, per="flow")
    with pytest.raises(ValueError, match="^tangent0 must have shape"):
        jb.fli(ROTOR, state, 10, tangent0=jnp.ones(4))
    with pytest.raises(ValueError, match="^tangent0 must be finite"):
        jb.megno(ROTOR, state, 10, tangent0=jnp.zeros(6))
    # A perturbation of the lens's constant alpha or zero spin is no perturbation of its dynamics.
    with pytest.raises(ValueError, match="^tangent0 must be finite"):
        jb.fli(LENS, jnp.asarray(LENS_REGULAR), 10, tangent0=jnp.asarray([0, 0, 1.0, 0, 0, 1.0]))
    # The collision map annihilates the flow direction: nothing would be left to follow.
    with pytest.raises(ValueError, match="^tangent0 must be finite"):
        jb.fli(ROTOR, state, 10, tangent0=ROTOR.phase_velocity(state))
    with pytest.raises(ValueError, match="^tangent0 must have shape"):
        jb.fli_map(ROTOR, state[None], 10, tangent0=jnp.ones((1, 6)))
