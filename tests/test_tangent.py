"""Tangent maps of the collision map and of the flow (jaxbill._engine.tangent).

* Central finite differences in float64 agree with the autodiff Jacobians to
  relative 1e-6 on random states away from corners and grazing, for every kind
  of scene, in the state and in the scene's parameters.
* Forward and reverse mode agree to rounding.
* For infinite inertia the static lens is a billiard of circular arcs; the flow
  tangent map equals the Dellago-Posch-Hoover formula for a focusing circular
  wall (implemented independently in ``dph_reference.py``), and the collision
  map's Jacobian equals it plus ``f(s') (grad tau)^T`` with ``grad tau`` from
  the same reference.
* Structure: the collision map kills the flow direction (rank 5), the flow map
  sends ``f(s)`` to ``f(s')``, and in canonical coordinates
  ``(x, y, alpha, M vx, M vy, I omega)`` the flow tangent map of the spinning
  stick is symplectic.
"""

from __future__ import annotations

import os
import sys

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbill as jb
from jaxbill._engine.collision import collide_unchecked
from jaxbill._engine.tangent import dynamical_indices, phase_velocity, tangent_map

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import dph_reference as dph

SCENES = {
    "rotor_ell1": dict(R=2.0, ell=1.0),
    "rotor_ell1.9": dict(R=2.0, ell=1.9),
    "rotor_ell0.5": dict(R=2.0, ell=0.5),
    "rotor_light": dict(R=2.0, ell=1.5, inertia=1.5**2 / 100),
    "lens": dict(R=2.0, ell=1.5, inertia=float("inf")),
    "circle": dict(R=2.0, ell=0.0),
}
N_STATES = 8
FD_STEP = 1e-6
FD_RTOL = 1e-6


def well_conditioned_states(scene, count, seed):
    """Random states inside the circle whose next collision is neither grazing
    (normal speed of the contact point >= 0.2 of its speed) nor near a corner
    (the other end's gap >= 0.05 R^2), with a flight time >= 0.05 R / speed."""
    rng = np.random.default_rng(seed)
    R, ell = float(scene.R), float(scene.ell)
    out = []
    while len(out) < count:
        reach = np.sqrt(R**2 - ell**2)
        c = rng.uniform(-reach, reach, 2)
        a = rng.uniform(-np.pi, np.pi)
        u = np.array([np.cos(a), np.sin(a)])
        if max(np.linalg.norm(c + ell * u), np.linalg.norm(c - ell * u)) > R - 0.05 * (R - ell):
            continue
        th = rng.uniform(-np.pi, np.pi)
        omega = 0.0 if scene.kind == "lens" else rng.uniform(-1, 1) * (0.5 / max(ell, 0.3))
        s = np.array([c[0], c[1], a, np.cos(th), np.sin(th), omega])
        _, dt, contact = _collide_jit(scene, jnp.asarray(s))
        dt, contact = float(dt), int(contact)
        if contact not in (1, -1) or dt < 0.05 * R:
            continue
        pre = np.asarray(scene.flight(jnp.asarray(s), dt))
        k = contact
        ua = np.array([np.cos(pre[2]), np.sin(pre[2])])
        p = pre[:2] + k * ell * ua
        w = pre[3:5] + k * ell * pre[5] * np.array([-ua[1], ua[0]])
        normal_speed = (p / np.linalg.norm(p)) @ w
        other_gap = R**2 - np.sum((pre[:2] - k * ell * ua) ** 2)
        if normal_speed < 0.2 * np.linalg.norm(w) or (ell > 0 and other_gap < 0.05 * R**2):
            continue
        out.append(s)
    return np.array(out)


_collide_jit = jax.jit(collide_unchecked)


@pytest.fixture(scope="module", params=list(SCENES))
def scene(request):
    return jb.StickInCircle(**SCENES[request.param])


_map_jit = jax.jit(lambda sc, s: collide_unchecked(sc, s)[:2])
_tangent_jit = jax.jit(tangent_map, static_argnames=("flow", "mode"))


def _central_difference(scene, s, idx):
    jac = np.zeros((6, 6))
    dtime = np.zeros(6)
    for i in idx:
        e = np.zeros(6)
        e[i] = FD_STEP
        plus, t_plus = _map_jit(scene, jnp.asarray(s + e))
        minus, t_minus = _map_jit(scene, jnp.asarray(s - e))
        diff = np.asarray(plus) - np.asarray(minus)
        diff[2] = (diff[2] + np.pi) % (2 * np.pi) - np.pi  # alpha is wrapped
        jac[:, i] = diff / (2 * FD_STEP)
        dtime[i] = (float(t_plus) - float(t_minus)) / (2 * FD_STEP)
    return jac, dtime


def test_collision_map_jacobian_matches_central_differences(scene):
    idx = dynamical_indices(scene)
    for s in well_conditioned_states(scene, N_STATES, seed=1):
        new, _, _, jac = _tangent_jit(scene, jnp.asarray(s))
        fd, _ = _central_difference(scene, s, idx)
        ix = np.ix_(idx, idx)
        j, f = np.asarray(jac)[ix], fd[ix]
        assert np.max(np.abs(j - f)) <= FD_RTOL * np.max(np.abs(j)), (s, np.max(np.abs(j - f)))


def test_flow_tangent_matches_central_differences(scene):
    """The flow tangent from finite differences: DP - f(s') (grad t)^T with both from FD."""
    idx = dynamical_indices(scene)
    for s in well_conditioned_states(scene, N_STATES, seed=2):
        new, _, _, jac = _tangent_jit(scene, jnp.asarray(s), flow=True)
        fd, dtime = _central_difference(scene, s, idx)
        fd = fd - np.outer(np.asarray(phase_velocity(new)), dtime)
        ix = np.ix_(idx, idx)
        j, f = np.asarray(jac)[ix], fd[ix]
        assert np.max(np.abs(j - f)) <= FD_RTOL * np.max(np.abs(j))


def test_forward_and_reverse_mode_agree(scene):
    for s in well_conditioned_states(scene, 3, seed=3):
        jf = np.asarray(_tangent_jit(scene, jnp.asarray(s), mode="forward")[3])
        jr = np.asarray(_tangent_jit(scene, jnp.asarray(s), mode="reverse")[3])
        np.testing.assert_allclose(jf, jr, rtol=0, atol=1e-12 * np.max(np.abs(jf)))


_parameter_jacobian = jax.jit(lambda sc, s: jax.jacfwd(lambda sc_: collide_unchecked(sc_, s)[:2])(sc))


def test_parameter_derivatives_match_central_differences(scene):
    """d(new state, dt)/d(R, ell, mass, inertia) by jacfwd against central differences."""
    names = ["R", "mass"] + (["ell"] if scene.kind != "circle" else []) + (["inertia"] if scene.kind == "rotor" else [])
    for s in well_conditioned_states(scene, 4, seed=4):
        s = jnp.asarray(s)
        grads = _parameter_jacobian(scene, s)
        for name in names:
            value = float(getattr(scene, name))
            h = FD_STEP * max(1.0, abs(value))
            plus = _map_jit(eqx.tree_at(lambda x: getattr(x, name), scene, jnp.asarray(value + h)), s)
            minus = _map_jit(eqx.tree_at(lambda x: getattr(x, name), scene, jnp.asarray(value - h)), s)
            for k in range(2):
                fd = (np.asarray(plus[k]) - np.asarray(minus[k])) / (2 * h)
                ad = np.asarray(getattr(grads[k], name))
                scale = max(np.max(np.abs(ad)), 1e-3)
                assert np.max(np.abs(ad - fd)) <= FD_RTOL * scale, (name, k, ad, fd)


def test_lens_tangent_equals_dellago_posch_hoover():
    R, ell = 2.0, 1.5
    scene = jb.StickInCircle(R=R, ell=ell, inertia=float("inf"))
    idx = list(dynamical_indices(scene))
    for s in well_conditioned_states(scene, 12, seed=5):
        q, v, alpha = s[:2], s[3:5], s[2]
        t, centre = dph.lens_collision(R, ell, alpha, q, v)
        ref_flow, q_c, v_out = dph.dph_flow_tangent(q, v, t, centre, R, kappa=-1.0)
        grad_tau = dph.dph_collision_time_gradient(q, v, t, centre, R, kappa=-1.0)
        new, dt, _, flow_jac = _tangent_jit(scene, jnp.asarray(s), flow=True)
        _, _, _, map_jac = _tangent_jit(scene, jnp.asarray(s), flow=False)
        # The reference's own base point agrees with jaxbill's collision.
        np.testing.assert_allclose(float(dt), t, rtol=1e-12)
        np.testing.assert_allclose(np.asarray(new)[[0, 1, 3, 4]], np.concatenate([q_c, v_out]), atol=1e-12)
        flow_jac = np.asarray(flow_jac)[np.ix_(idx, idx)]
        np.testing.assert_allclose(flow_jac, ref_flow, rtol=0, atol=1e-10 * np.max(np.abs(ref_flow)))
        ref_map = ref_flow + np.outer(np.concatenate([v_out, [0.0, 0.0]]), grad_tau)
        map_jac = np.asarray(map_jac)[np.ix_(idx, idx)]
        np.testing.assert_allclose(map_jac, ref_map, rtol=0, atol=1e-10 * np.max(np.abs(ref_map)))


def test_dph_reference_against_finite_differences():
    """The reference itself, checked against its own closed-form collision (no jaxbill)."""
    R, ell, alpha = 2.0, 1.5, 0.3
    q, v = np.array([0.1, -0.2]), np.array([0.6, 0.8])
    t, centre = dph.lens_collision(R, ell, alpha, q, v)

    def flow_state(x, time):
        """State at a fixed time ``time`` (past the collision) from the start ``x``."""
        tc, cc = dph.lens_collision(R, ell, alpha, x[:2], x[2:])
        q_c = x[:2] + x[2:] * tc
        n = -(q_c - cc) / R
        v_out = x[2:] - 2 * (x[2:] @ n) * n
        return np.concatenate([q_c + v_out * (time - tc), v_out])

    x0 = np.concatenate([q, v])
    fd = np.zeros((4, 4))
    for j in range(4):
        e = np.zeros(4)
        e[j] = 1e-6
        fd[:, j] = (flow_state(x0 + e, t) - flow_state(x0 - e, t)) / 2e-6
    ref, _, _ = dph.dph_flow_tangent(q, v, t, centre, R, kappa=-1.0)
    np.testing.assert_allclose(ref, fd, atol=1e-6 * np.max(np.abs(ref)))


@pytest.mark.parametrize("name", ["rotor_ell1", "rotor_light", "lens", "circle"])
def test_tangent_structure(name):
    """DP f(s) = 0, D phi f(s) = f(s'), and the flow map is symplectic in canonical coordinates."""
    scene = jb.StickInCircle(**SCENES[name])
    idx = list(dynamical_indices(scene))
    n = len(idx)
    mass = float(scene.mass)
    inertia = float(scene.inertia) if scene.kind == "rotor" else 1.0
    weights = np.array([1.0, 1.0, 1.0, mass, mass, inertia])[idx]
    omega = np.block([[np.zeros((n // 2, n // 2)), np.eye(n // 2)], [-np.eye(n // 2), np.zeros((n // 2, n // 2))]])
    for s in well_conditioned_states(scene, 4, seed=6):
        f = np.asarray(phase_velocity(jnp.asarray(s)))
        new, _, _, dp = _tangent_jit(scene, jnp.asarray(s))
        _, _, _, dphi = _tangent_jit(scene, jnp.asarray(s), flow=True)
        dp, dphi = np.asarray(dp)[np.ix_(idx, idx)], np.asarray(dphi)[np.ix_(idx, idx)]
        f, f_new = f[idx], np.asarray(phase_velocity(new))[idx]
        scale = np.max(np.abs(dphi))
        assert np.max(np.abs(dp @ f)) <= 1e-12 * scale
        assert np.max(np.abs(dphi @ f - f_new)) <= 1e-12 * scale
        canonical = weights[:, None] * dphi / weights[None, :]
        np.testing.assert_allclose(canonical.T @ omega @ canonical, omega, atol=1e-11 * scale**2)


def test_tangent_map_under_vmap_and_bad_mode():
    scene = jb.StickInCircle(R=2.0, ell=1.0)
    states = jnp.asarray(well_conditioned_states(scene, 3, seed=7))
    batch = jax.jit(jax.vmap(lambda s: tangent_map(scene, s)[3]))(states)
    for k in range(3):
        np.testing.assert_allclose(batch[k], _tangent_jit(scene, states[k])[3], rtol=1e-13, atol=1e-13)
    with pytest.raises(ValueError, match="mode"):
        tangent_map(scene, states[0], mode="sideways")


def test_the_lens_direction_held_fixed_pushes_vectors_as_recomputed():
    """``push_forward`` with the orbit's constants (the static lens's direction, computed once from the
    first state) moves the state bitwise and tangent vectors of the dynamical frame to rounding as when
    the direction is recomputed, and differentiated, at every collision."""
    from jaxbill._engine.step import orbit_constants
    from jaxbill._engine.tangent import dynamical_frame, push_forward

    scene = jb.StickInCircle(R=2.0, ell=1.5, inertia=float("inf"))
    state0 = jnp.asarray([0.434, -0.323, -1.554, 0.991, -0.131, 0.0])
    constants = orbit_constants(scene, state0)

    @jax.jit  # one program for the 20 collisions (eagerly, each operation was dispatched alone: 46 s)
    def both_pushes(state):
        vectors = dynamical_frame(scene, state)
        fixed = push_forward(scene, state, vectors, flow=True, constants=constants)
        return fixed, push_forward(scene, state, vectors, flow=True)

    state = state0
    for _ in range(20):
        fixed, recomputed = both_pushes(state)
        np.testing.assert_array_equal(fixed[0], recomputed[0])
        np.testing.assert_allclose(fixed[3], recomputed[3], rtol=1e-14, atol=1e-14)
        state = fixed[0]


@pytest.mark.parametrize(
    "scene, start, flow",
    [
        (jb.StickInCircle(R=2.0, ell=1.9), [0.02, -0.01, 0.3, 0.8, -0.5, 0.7], True),
        (jb.StickInCircle(R=2.0, ell=1.5, inertia=float("inf")), [0.434, -0.323, -1.554, 0.991, -0.131, 0.0], True),
        (jb.StickInCircle(R=2.0, ell=0.0, inertia=float("inf")), [0.5, -0.3, 0.0, 0.6, 0.8, 0.0], False),
        (jb.StickBetweenWalls2D(h=3.0, ell=1.0), [0.0, 1.5, 0.3, 0.4, 0.9, 1.1], False),
    ],
    ids=["rotor-flow", "lens-flow", "circle-section", "walls2d-section"],
)
def test_a_frame_pushed_in_its_dynamical_coordinates_is_the_full_states_push(scene, start, flow):
    """``push_frame`` differentiates only the coordinates that carry the dynamics (the lens's and the
    circle's ``alpha`` and ``omega`` get no tangent at all): over 10 collisions, state and frame bitwise
    as when the frame is written into whole state vectors, pushed (``push_forward``) and read back."""
    from jaxbill._engine.step import orbit_constants
    from jaxbill._engine.tangent import dynamical_size, push_forward, push_frame, to_dynamical, to_state_space

    state = jnp.asarray(start)
    constants = orbit_constants(scene, state)
    k = dynamical_size(scene)
    frame = jnp.asarray(np.linalg.qr(np.random.default_rng(3).standard_normal((k, k)))[0])

    @jax.jit
    def both(s, q):
        by_frame = push_frame(scene, s, q, flow=flow, constants=constants)
        new_state, dt, contact, vectors = push_forward(
            scene, s, to_state_space(scene, s, q), flow=flow, constants=constants
        )
        return by_frame, (new_state, dt, contact, to_dynamical(scene, new_state, vectors))

    for _ in range(10):
        got, expected = both(state, frame)
        for a, b in zip(got, expected, strict=True):
            np.testing.assert_array_equal(a, b)
        state, frame = got[0], got[3] / jnp.linalg.norm(got[3], axis=0)
