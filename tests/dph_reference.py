"""Independent references for the tangent-map tests (numpy only, no jaxbill code).

* ``dph_flow_tangent``: the Dellago-Posch-Hoover tangent map of a point
  particle (mass 1) that flies freely for a time ``t`` and then reflects
  specularly off a circular wall of radius ``R`` centred at ``C``, in the
  published compact form (C. Dellago, H. A. Posch and W. G. Hoover, Phys. Rev. E
  53, 1485 (1996); the same form is used by DynamicalBilliards.jl)::

      dq' = dq - 2 (dq . n) n
      dp' = dp - 2 (dp . n) n - 2 kappa (dq . t_in) / (R cos) t_out

  with ``dq, dp`` the perturbation carried by free flight to the collision
  instant, ``n`` the wall normal pointing into the billiard, ``cos = -n . v_in``,
  ``t_in = (-v_in_y, v_in_x)`` and ``t_out`` the same for ``v_out``; ``kappa = -1``
  for a focusing wall (the particle inside the circle, as for the arcs of the
  lens) and ``+1`` for a dispersing one. It compares orbits at a fixed time
  (the reference collision time), so it is the flow's tangent map.

* ``dph_collision_time_gradient``: the first-order change of the collision time,
  ``d tau = -(n . dq_c) / (n . v)`` with ``dq_c = dq + t dp``.

* ``lens_collision``: the lens billiard's next collision (closed form), for the
  reference's base point.
"""

from __future__ import annotations

import numpy as np


def _perp(v):
    return np.array([-v[1], v[0]])


def lens_collision(R, ell, alpha, q, v):
    """Next wall contact of a point at ``q`` with velocity ``v`` inside the lens.

    The lens is the intersection of the discs of radius ``R`` centred at
    ``-k ell u`` (``k = +1, -1``; ``u = (cos alpha, sin alpha)``). Returns
    ``(t, centre)``: the flight time and the centre of the arc that is hit.
    """
    u = np.array([np.cos(alpha), np.sin(alpha)])
    best = (np.inf, None)
    for k in (1.0, -1.0):
        centre = -k * ell * u
        d = q - centre
        a, b, c = v @ v, d @ v, d @ d - R * R
        t = (-b + np.sqrt(b * b - a * c)) / a  # leaving the disc: the larger root
        if t < best[0]:
            best = (t, centre)
    return best


def dph_flow_tangent(q, v, t, centre, R, kappa=-1.0):
    """4x4 DPH tangent map on ``(dq, dp)`` (mass 1) over a flight of ``t`` and a reflection.

    Rows/columns are ``(x, y, vx, vy)``. ``q, v`` are the position and velocity at
    the start of the flight.
    """
    q_c = q + v * t
    n = -(q_c - centre) / R if kappa < 0 else (q_c - centre) / R
    v_out = v - 2 * (v @ n) * n
    cos = -(n @ v)
    t_in, t_out = _perp(v), _perp(v_out)
    m = np.zeros((4, 4))
    for j in range(4):
        e = np.zeros(4)
        e[j] = 1.0
        dq, dp = e[:2] + t * e[2:], e[2:]
        dq_new = dq - 2 * (dq @ n) * n
        dp_new = dp - 2 * (dp @ n) * n - 2 * kappa * (dq @ t_in) / (R * cos) * t_out
        m[:, j] = np.concatenate([dq_new, dp_new])
    return m, q_c, v_out


def dph_collision_time_gradient(q, v, t, centre, R, kappa=-1.0):
    """Gradient of the collision time with respect to ``(x, y, vx, vy)`` at the start."""
    q_c = q + v * t
    n = -(q_c - centre) / R if kappa < 0 else (q_c - centre) / R
    grad = np.zeros(4)
    for j in range(4):
        e = np.zeros(4)
        e[j] = 1.0
        dq_c = e[:2] + t * e[2:]
        grad[j] = -(n @ dq_c) / (n @ v)
    return grad
