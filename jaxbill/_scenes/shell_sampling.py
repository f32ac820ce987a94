"""Starts on an energy shell with the Liouville measure: what each scene's ``sample_states`` draws.

``jb.sample_energy_shell`` loops over a scene's ``sample_states`` until it has
enough; the candidates come from here. Configurations are drawn uniformly and
kept where the body is inside; velocities uniformly on the shell's sphere in
the mass-weighted coordinates ``pi = (sqrt(M) vx, sqrt(M) vy, sqrt(I) omega)``
(``|pi|^2 = 2E``), or on its circle at fixed angular momentum, weighted by
``1 / |b(q)|`` (see ``jb.sample_energy_shell``).
"""

from __future__ import annotations

import math

import numpy as np


def _velocities_on_shell(rng, c: np.ndarray, mass: float, inertia: float, turning: bool, energy, angular_momentum):
    """Velocities ``(k, 3)`` of a planar body at centres ``c`` ``(k, 2)`` on the shell ``E`` (and ``L``), with
    ``(kept (k,) bool, weights (kept,))`` (see ``sample_energy_shell``)."""
    k = len(c)
    if not turning:
        theta = rng.uniform(-np.pi, np.pi, k)
        v = np.sqrt(2 * energy / mass) * np.stack([np.cos(theta), np.sin(theta)], 1)
        return np.column_stack([v, np.zeros(k)]), np.ones(k, bool), np.ones(k)
    if angular_momentum is None:
        pi = rng.standard_normal((k, 3))
        pi *= np.sqrt(2 * energy) / np.linalg.norm(pi, axis=1)[:, None]
        return np.column_stack([pi[:, 0:2] / np.sqrt(mass), pi[:, 2] / np.sqrt(inertia)]), np.ones(k, bool), np.ones(k)
    b = np.stack([-np.sqrt(mass) * c[:, 1], np.sqrt(mass) * c[:, 0], np.full(k, np.sqrt(inertia))], 1)
    bnorm = np.linalg.norm(b, axis=1)
    d = angular_momentum / bnorm
    reach = 2 * energy - d * d
    keep = reach > 0
    b, bnorm, d, reach = b[keep], bnorm[keep], d[keep], reach[keep]
    bhat = b / bnorm[:, None]
    # Orthonormal basis of the plane perpendicular to bhat.
    e1 = np.cross(bhat, np.array([0.0, 0.0, 1.0]))
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    e2 = np.cross(bhat, e1)
    psi = rng.uniform(-np.pi, np.pi, len(d))
    r = np.sqrt(reach)
    pi = d[:, None] * bhat + r[:, None] * (np.cos(psi)[:, None] * e1 + np.sin(psi)[:, None] * e2)
    velocities = np.column_stack([pi[:, 0:2] / np.sqrt(mass), pi[:, 2] / np.sqrt(inertia)])
    return velocities, keep, 1.0 / bnorm


def circle_shell_candidates(scene, rng, m: int, energy: float, angular_momentum=None, margin: float = 1e-9):
    """``StickInCircle.sample_states``: ``m`` tries, the ``(states (k, 6), weights (k,))`` kept (see
    ``sample_energy_shell``); configurations uniform in the square ``[-R, R]^2 x [-pi, pi)``, kept when both
    ends are inside by ``margin R``."""
    R = float(scene.R)
    ell = float(scene.ell)
    if angular_momentum is not None and scene.kind != "rotor":
        raise ValueError("angular_momentum is conserved only for a spinning stick (finite inertia, ell > 0)")
    c = rng.uniform(-R, R, (m, 2))
    alpha = rng.uniform(-np.pi, np.pi, m)
    u = np.stack([np.cos(alpha), np.sin(alpha)], axis=1)
    inside = np.maximum(np.linalg.norm(c + ell * u, axis=1), np.linalg.norm(c - ell * u, axis=1)) < R * (1 - margin)
    c, alpha = c[inside], alpha[inside]
    turning = scene.kind == "rotor"
    inertia = float(scene.inertia) if turning else 0.0
    velocities, keep, w = _velocities_on_shell(rng, c, float(scene.mass), inertia, turning, energy, angular_momentum)
    return np.column_stack([c[keep], alpha[keep], velocities]), w


def table_shell_candidates(scene, rng, m: int, energy: float, angular_momentum=None, margin: float = 1e-9):
    """Energy-shell tries for a planar body ``[x, y, alpha, vx, vy, omega]`` in a fixed table.

    Configurations uniform in the table's box (``scene.table.extent``; along an
    unbounded direction, ``+-`` its size) times ``[-pi, pi)``, kept where every
    contact point's clearance (``Table.clearance``: every gap, for a table that
    is an intersection of walls; a periodic table's central cell) exceeds
    ``margin * gap_scale``; velocities uniform on the sphere
    ``|(sqrt(M) v, sqrt(I) omega)|^2 = 2E`` (on the circle ``sqrt(M)|v| = sqrt(2E)``,
    ``omega = 0``, for a body that never turns or a point). With
    ``angular_momentum`` (a turning body in a table that conserves it), on the
    shell's circle at fixed ``L``, weighted as ``sample_energy_shell`` says.
    Returns ``(states (k, 6), weights (k,))``.
    """
    turning = scene.body.kind == "rotor"
    if angular_momentum is not None and not (turning and scene.conserves_angular_momentum):
        raise ValueError(
            f"angular_momentum: {type(scene).__name__} conserves none "
            "(only a turning body in a circle does); leave it None"
        )
    size = float(scene.length_scale)
    # Only an unbounded direction (along the strip) is cut to +- the size: a bounded table's whole box is
    # drawn from, or configurations beyond the size (the ends of an ellipse, sqrt(ab) < a) are never drawn.
    x_low, x_high, y_low, y_high = (
        bound if math.isfinite(bound) else math.copysign(size, bound) for bound in map(float, scene.table.extent)
    )
    middle = np.array([0.5 * (x_low + x_high), 0.5 * (y_low + y_high)])
    half = np.array([0.5 * (x_high - x_low), 0.5 * (y_high - y_low)])
    c = middle + rng.uniform(-1.0, 1.0, (m, 2)) * half
    alpha = rng.uniform(-np.pi, np.pi, m)
    trial = np.column_stack([c, alpha, np.zeros((m, 3))])
    inside = np.all(np.asarray(scene.clearances(trial)) > margin * float(scene.gap_scale), axis=1)
    c, alpha = c[inside], alpha[inside]
    inertia = float(scene.inertia) if turning else 0.0
    velocities, keep, w = _velocities_on_shell(rng, c, float(scene.mass), inertia, turning, energy, angular_momentum)
    return np.column_stack([c[keep], alpha[keep], velocities]), w
