"""Poincaré-section coordinates, computed from the state at a collision.

Every function here is a pure ``jax.numpy`` function of a scene and a batch of
states ``(..., 6) = [x, y, alpha, vx, vy, omega]`` taken *at* a collision (as
in ``jb.orbit(...).state``, the states just after each impulse); it returns
``(..., 2)`` and works under ``jit``, ``vmap`` and ``grad``. Positions are the
same just before and just after an impulse; only the velocities differ (see
``incoming_states``).

Three sections
==============

**The paper's projection** (``paper_section``). Chatterjee and Jackson plot, at
each collision, ``L_z = y p_x - x p_y`` against ``phi_c = arctan(p_y / p_x)``
in units of ``pi``, with ``p = M v`` the momentum of the stick's centre. Both
are kept exactly as the paper writes them: ``L_z`` is *minus* the usual
orbital angular momentum ``x p_y - y p_x`` of the centre, and ``arctan`` (not
``arctan2``) folds a direction and its reverse onto one value, so
``phi_c`` lies in ``[-1/2, 1/2]``. The system has five phase-space dimensions
at fixed energy, so these two numbers are a projection of a four-dimensional
section: orbits with different total angular momentum ``L`` overlap in it.
The paper calls ``phi_c`` the angle "of incidence" without saying whether the
momentum is taken before or after the impulse; applied to
``jb.orbit(...).state`` (as ``jaxbill figures`` does) the momentum is the one
just after it, and ``incoming_states`` gives the states just before it.

**The reduced section** (``reduced_section``, finite inertia). The total
angular momentum ``L = M (x v_y - y v_x) + I omega`` is conserved and the
dynamics is invariant under turning the whole picture (centre and stick) about
the origin. At fixed ``E`` and ``L`` with that rotation divided out, two
degrees of freedom remain, and the collisions form an honest two-dimensional
Poincaré map on which KAM curves separate regions. Its coordinates are the
wall's own Birkhoff coordinates in the frame that turns with the stick (the
paper's "rotating billiard wall"):

* ``s`` -- where on the lens-shaped wall the contact is, as arc length along
  the wall in the stick's frame. At a contact of end ``k`` (``P_k = c + k ell u``
  on the circle, at polar angle ``Phi``) let ``beta = Phi - alpha_k`` be the
  angle between the stick (pointing from the centre to the touching end,
  ``alpha_k = alpha`` for P1, ``alpha + pi`` for P2) and the radius to the
  contact point. The stick lies inside the circle, so
  ``|beta| <= beta_max = arccos(ell / R)``; at ``|beta| = beta_max`` both ends
  touch (a corner of the lens). Then ``s = R (beta + beta_max)`` on the arc
  of P1 and ``s = R (beta + 3 beta_max)`` on the arc of P2, so ``s`` runs
  once round the lens, ``0 <= s < 4 R beta_max`` (``wall_length``), anticlockwise
  in the stick's frame, starting at a corner. Rotating the picture leaves
  ``beta`` and ``k`` unchanged: they are functions on the reduced space.
* ``p = sqrt(M) v_t / sqrt(2 E)`` -- the tangential momentum of the centre at
  the contact, ``v_t = v . t``, ``t = (-sin Phi, cos Phi)`` the anticlockwise
  tangent of the circle at the contact, in units of ``sqrt(2 M E)``: a
  number in ``[-1, 1]``, the sine of a reflection angle. The impulse is
  radial, so ``p`` is the same just before and just after a collision.

Why these: on the contact surface the configuration is fixed by ``beta`` and
the stick angle ``alpha``; the rotation shifts ``alpha`` alone, and the momentum
conjugate to ``alpha`` at fixed ``beta`` is ``L`` itself. The momentum
conjugate to ``beta`` at fixed ``alpha`` is ``M R v_t`` (moving the contact
along the wall with the stick held moves the centre along ``R t``). A billiard's
collision map preserves ``sum dq dp`` over the tangential coordinates, so after
reduction at fixed ``L`` the pair ``(R beta, M v_t)`` -- and hence ``(s, p)``,
which differ by constant factors and shifts -- is area-preserving: equal areas
of the ``(s, p)`` plane have equal phase-space weight, and "fraction of the
section covered" is meaningful. ``(s, p)``, ``E`` and ``L`` determine the state
just after the collision up to the rotation (``section_state`` inverts them).
The region reachable at ``(E, L)`` is ``p_min(s) <= p <= p_max(s)``
(``reduced_section_bounds``); a plot must hold one ``(E, L)`` only.
Relabelling the ends (``alpha -> alpha + pi``, the same physical stick) moves
``s`` by half the wall length and keeps ``p``: the two halves of every reduced
picture are copies of each other. Checked numerically (``tests/test_sections.py``,
notebook 03): the Jacobian of the collision map in ``(s, p)`` has determinant 1
to ``1e-14``; a regular orbit draws one smooth closed curve (a Fourier fit of
its radius leaves ``~1e-6`` relative residual), a chaotic one fills an area
bounded by such curves.

**Birkhoff coordinates** (``birkhoff_section``) for the two limits with a fixed
billiard table, as a point particle (the centre) reflecting specularly:

* static lens (``inertia = inf``): the centre moves in the fixed lens, the
  intersection of the discs of radius ``R`` about ``-ell u`` and ``+ell u``.
  Its arc of P1 is the circle about ``-ell u`` at which P1 touches; the
  arc length along the lens boundary is ``s = R (beta + beta_max)`` on the arc
  of P1 and ``R (beta + 3 beta_max)`` on the arc of P2 (the same formula as the
  reduced section: each arc has radius ``R`` and turns through ``2 beta_max``);
  ``p = v_t / |v| = sin(chi)``, ``chi`` the angle of the outgoing velocity
  from the inward normal, positive when the particle moves anticlockwise;
* circle (``ell = 0``): ``s = R Phi`` with ``Phi`` the polar angle of the
  centre in ``[0, 2 pi)``, ``p = v_t / |v| = sin(chi)``. The circle is
  integrable: ``p`` is constant along every orbit.

So ``reduced_section`` of a lens or circle scene *is* its Birkhoff section: a
static wall is the ``I -> inf`` limit of the rotating one.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from jaxbill._engine.validation import MAX_STORED_COUNT, as_states, check_count, require_x64
from jaxbill._scenes.protocols import SectionChart, end_points


def paper_section(scene, states: Float[ArrayLike, "*batch 6"]) -> Float[Array, "*batch 2"]:
    """The paper's projected section: ``[L_z, phi_c]`` with ``phi_c`` in units of ``pi``.

    ``L_z = y p_x - x p_y`` (units mass * length^2 / time; the paper's sign,
    minus the centre's usual orbital angular momentum) and
    ``phi_c = arctan(p_y / p_x) / pi`` in ``[-1/2, 1/2]`` (the paper's
    ``arctan``, which does not tell ``p`` from ``-p``), with ``p = M (vx, vy)``.

    Args:
        scene: a ``StickInCircle`` (only ``mass`` is used).
        states: ``(..., 6)`` states at collisions.

    Returns:
        ``(..., 2)`` array ``[L_z, phi_c]``.
    """
    states = as_states(scene, states)
    x, y, vx, vy = states[..., 0], states[..., 1], states[..., 3], states[..., 4]
    px, py = scene.mass * vx, scene.mass * vy
    l_z = y * px - x * py
    # arctan(py/px) with px = 0 is +-pi/2 (arctan of +-inf); 0/0 gives NaN.
    phi_c = jnp.arctan(py / px) / jnp.pi
    return jnp.stack([l_z, phi_c], axis=-1)


def contact_end(scene, states: jax.Array) -> jax.Array:
    """The end on the wall in each state: ``+1`` (P1) or ``-1`` (P2); the one with the smaller gap."""
    gaps = jnp.abs(scene.gaps(jnp.asarray(states)))
    return jnp.where(gaps[..., 0] <= gaps[..., 1], 1, -1).astype(jnp.int32)


def half_corner_angle(scene) -> jax.Array:
    """``beta_max = arccos(ell / R)``: the largest angle between the stick and the radius at a contact.

    ``pi / 2`` for the circle (``ell = 0``).
    """
    return jnp.arccos(scene.ell / scene.R)


def wall_length(scene) -> Float[Array, "*scenes"]:
    """Length of the section's ``s`` axis: ``4 R beta_max`` for a stick, ``2 pi R`` for the circle."""
    if scene.kind == "circle":
        return 2.0 * jnp.pi * scene.R
    return 4.0 * scene.R * half_corner_angle(scene)


def _contact_geometry(scene, states: jax.Array):
    """Contact angle ``Phi``, arm angle ``beta``, touching end and unit vectors at the contact."""
    x, y, alpha = states[..., 0], states[..., 1], states[..., 2]
    end = contact_end(scene, states)
    arm = end * scene.ell
    px, py = x + arm * jnp.cos(alpha), y + arm * jnp.sin(alpha)
    phi = jnp.arctan2(py, px)
    alpha_k = alpha + jnp.where(end == 1, 0.0, jnp.pi)
    beta = jnp.remainder(phi - alpha_k + jnp.pi, 2.0 * jnp.pi) - jnp.pi
    return phi, beta, end


def _tangential_velocity(states: jax.Array, phi: jax.Array) -> jax.Array:
    return -jnp.sin(phi) * states[..., 3] + jnp.cos(phi) * states[..., 4]


def _wall_coordinate(scene, states: jax.Array):
    phi, beta, end = _contact_geometry(scene, states)
    if scene.kind == "circle":
        s = scene.R * jnp.remainder(phi, 2.0 * jnp.pi)
    else:
        beta_max = half_corner_angle(scene)
        s = scene.R * (beta + jnp.where(end == 1, 1.0, 3.0) * beta_max)
        s = jnp.remainder(s, wall_length(scene))
    return s, phi


def reduced_section(scene, states: Float[ArrayLike, "*batch 6"]) -> Float[Array, "*batch 2"]:
    """The section of the symmetry-reduced system: ``[s, p]`` (see the module docstring).

    ``s`` is the arc length of the contact along the lens-shaped wall in the
    stick's frame (``0 <= s < wall_length(scene)``, length units) and
    ``p = sqrt(M) v_t / sqrt(2 E)`` the centre's tangential momentum at the
    contact in units of ``sqrt(2 M E)`` (dimensionless, in ``[-1, 1]``),
    ``E`` the energy of each state. The pair is area-preserving for the
    collision map at fixed ``(E, L)``; plot orbits of one ``(E, L)`` together.
    For ``inertia = inf`` and ``ell = 0`` this is ``birkhoff_section``.

    Args:
        scene: a ``StickInCircle`` of any kind.
        states: ``(..., 6)`` states at collisions (one end on the wall).

    Returns:
        ``(..., 2)`` array ``[s, p]``.
    """
    states = as_states(scene, states)
    s, phi = _wall_coordinate(scene, states)
    v_t = _tangential_velocity(states, phi)
    p = jnp.sqrt(scene.mass) * v_t / jnp.sqrt(2.0 * scene.energy(states))
    return jnp.stack([s, p], axis=-1)


def birkhoff_section(scene, states: Float[ArrayLike, "*batch 6"]) -> Float[Array, "*batch 2"]:
    """Birkhoff coordinates ``[s, sin chi]`` of the centre on a fixed wall.

    For the static lens (``inertia = inf``): ``s`` the arc length along the
    lens boundary (``0 <= s < 4 R arccos(ell / R)``, starting at a corner,
    anticlockwise), for the circle (``ell = 0``): ``s = R Phi``,
    ``0 <= s < 2 pi R``. ``sin chi = v_t / |v|``, the tangential component of
    the outgoing unit velocity (anticlockwise positive).

    Raises:
        ValueError: for a spinning stick (finite inertia, ``ell > 0``): its
            wall moves; use ``reduced_section``.
    """
    if scene.kind == "rotor":
        raise ValueError(
            "birkhoff_section needs a fixed wall (inertia = inf or ell = 0); for a finite inertia use reduced_section"
        )
    return reduced_section(scene, states)


def reduced_section_bounds(
    scene, s: Float[ArrayLike, "*batch"], energy: ArrayLike, angular_momentum: ArrayLike
) -> Float[Array, "*batch 2"]:
    """The reachable range ``[p_min, p_max]`` of the reduced section at ``s`` for given ``E``, ``L``.

    At a contact at ``s`` the velocity ``V = (sqrt(M) v, sqrt(I) omega)`` has
    ``|V|^2 = 2 E`` and ``xi . V = L`` (``xi`` the rotation's generator); a
    tangential momentum ``p`` is reachable iff
    ``p^2 + (lambda - X p)^2 / Y^2 <= 1`` with ``lambda = L / sqrt(2 E)``,
    ``X = sqrt(M) (R - ell cos beta)``, ``Y^2 = M ell^2 sin^2 beta + I``.
    For the lens and the circle the range is ``[-1, 1]``.

    Returns:
        ``(..., 2)``; NaN where nothing is reachable.
    """
    s = jnp.asarray(s, dtype=jnp.float64)
    if scene.kind != "rotor":
        ones = jnp.ones_like(s)
        return jnp.stack([-ones, ones], axis=-1)
    beta, _ = _beta_from_s(scene, s)
    lam = angular_momentum / jnp.sqrt(2.0 * energy)
    big_x = jnp.sqrt(scene.mass) * (scene.R - scene.ell * jnp.cos(beta))
    y2 = scene.mass * (scene.ell * jnp.sin(beta)) ** 2 + scene.inertia
    # (Y^2 + X^2) p^2 - 2 lambda X p + lambda^2 - Y^2 <= 0
    a = y2 + big_x**2
    b = lam * big_x
    disc = b * b - a * (lam**2 - y2)
    root = jnp.sqrt(jnp.where(disc >= 0.0, disc, jnp.nan))
    return jnp.stack([(b - root) / a, (b + root) / a], axis=-1)


def _beta_from_s(scene, s: jax.Array):
    beta_max = half_corner_angle(scene)
    s = jnp.remainder(s, wall_length(scene))
    on_p1 = s < 2.0 * scene.R * beta_max
    beta = jnp.where(on_p1, s / scene.R - beta_max, s / scene.R - 3.0 * beta_max)
    return beta, jnp.where(on_p1, 1, -1)


def section_state(
    scene,
    s: Float[ArrayLike, "*#batch"],
    p: Float[ArrayLike, "*#batch"],
    energy: ArrayLike = 0.5,
    angular_momentum: ArrayLike = 0.0,
    rotation: ArrayLike = 0.0,
) -> Float[Array, "*batch 6"]:
    """The state just after a collision at the section point ``(s, p)``: the inverse of ``reduced_section``.

    Args:
        scene: a ``StickInCircle`` of any kind.
        s, p: section coordinates (arrays broadcast together), as returned by
            ``reduced_section`` / ``birkhoff_section``.
        energy: the energy ``E`` of the state.
        angular_momentum: the total ``L`` (finite inertia only; the lens and the
            circle ignore it: there ``p`` and ``s`` fix the orbital part).
        rotation: the stick angle ``alpha`` of the returned state (the
            rotation that the reduced section divides out, and for the lens
            its fixed orientation; default 0). Unused for the circle, whose
            ``s`` is the contact's polar angle itself.

    Returns:
        ``(..., 6)`` states with the touching end on the circle and moving
        inwards, ``reduced_section(scene, state) == (s, p)`` to rounding, energy
        ``E`` and (finite inertia) angular momentum ``L``. NaN where ``(s, p)``
        is not reachable at ``(E, L)`` (see ``reduced_section_bounds``). A lens
        corner (``|beta| = beta_max``) is a valid but ill-posed start.
    """
    s = jnp.asarray(s, dtype=jnp.float64)
    p = jnp.asarray(p, dtype=jnp.float64)
    s, p = jnp.broadcast_arrays(s, p)
    M, R, ell = scene.mass, scene.R, scene.ell
    speed = jnp.sqrt(2.0 * energy / M)
    if scene.kind == "circle":
        phi = s / R
        beta = jnp.zeros_like(s)
        end = jnp.ones_like(s, dtype=jnp.int32)
    else:
        beta, end = _beta_from_s(scene, s)
        alpha = jnp.zeros_like(s) + rotation
        phi = alpha + jnp.where(end == 1, 0.0, jnp.pi) + beta
    # Frame of the contact: n along x, t along y.
    v_t = p * jnp.sqrt(2.0 * energy / M)
    if scene.kind == "rotor":
        inertia = scene.inertia
        c_x = R - ell * jnp.cos(beta)
        c_y = ell * jnp.sin(beta)
        # omega = a + b v_n from L = M (c_x v_t - c_y v_n) + I omega
        a = (angular_momentum - M * c_x * v_t) / inertia
        b = M * c_y / inertia
        k = 2.0 * energy - M * v_t**2
        qa = M + inertia * b * b
        qb = inertia * a * b
        qc = inertia * a * a - k
        disc = qb * qb - qa * qc
        root = jnp.sqrt(jnp.where(disc >= 0.0, disc, jnp.nan))
        # The outgoing root: the touching end moves inwards, v_n + omega ell sin(beta) < 0,
        # and that normal speed is linear in v_n with positive slope 1 + b ell sin(beta).
        v_n = (-qb - root) / qa
        omega = a + b * v_n
    else:
        v_n = -jnp.sqrt(jnp.where(speed**2 - v_t**2 >= 0.0, speed**2 - v_t**2, jnp.nan))
        omega = jnp.zeros_like(v_n)
    cos_phi, sin_phi = jnp.cos(phi), jnp.sin(phi)
    vx = v_n * cos_phi - v_t * sin_phi
    vy = v_n * sin_phi + v_t * cos_phi
    contact = R * jnp.stack([cos_phi, sin_phi], axis=-1)
    if scene.kind == "circle":
        centre = contact
        alpha = jnp.zeros_like(s)
    else:
        alpha_k = phi - beta
        u_k = jnp.stack([jnp.cos(alpha_k), jnp.sin(alpha_k)], axis=-1)
        centre = contact - ell * u_k
        alpha = jnp.where(end == 1, alpha_k, alpha_k + jnp.pi)
        alpha = jnp.remainder(alpha + jnp.pi, 2.0 * jnp.pi) - jnp.pi
    state = jnp.stack([centre[..., 0], centre[..., 1], alpha, vx, vy, omega], axis=-1)
    return jnp.where(jnp.isfinite(v_n)[..., None], state, jnp.nan)


def incoming_states(
    states: Float[ArrayLike, "*batch n 6"], state0: Float[ArrayLike, "*batch 6"]
) -> Float[Array, "*batch n 6"]:
    """States just *before* each collision of an orbit, from the states just after.

    The impulse changes only velocities, and free flight keeps them, so the
    state before collision ``j`` has the position of ``states[j]`` and the
    velocities of ``states[j - 1]`` (of ``state0`` for ``j = 0``).

    Args:
        states: ``(..., n, 6)``, e.g. ``jb.orbit(scene, state0, n).state``.
        state0: ``(..., 6)`` the orbit's initial state.
    """
    states = jnp.asarray(states)
    state0 = jnp.asarray(state0, dtype=states.dtype)
    previous = jnp.concatenate([state0[..., None, :], states[..., :-1, :]], axis=-2)
    return jnp.concatenate([states[..., :3], previous[..., 3:]], axis=-1)


def halton(index: np.ndarray, base: int) -> np.ndarray:
    """Radical inverse of ``index`` in ``base``: a low-discrepancy sequence in ``[0, 1)``."""
    index = np.asarray(index, dtype=np.int64).copy()
    out = np.zeros(index.shape, dtype=np.float64)
    factor = 1.0 / base
    while np.any(index > 0):
        out += factor * (index % base)
        index //= base
        factor /= base
    return out


def section_seeds(
    scene, count: int, energy: float = 0.5, angular_momentum: float = 0.0, *, half: bool = True, offset: int = 1
) -> Float[Array, "count 6"]:
    """``count`` start states spread evenly over the reachable part of the ``(s, p)`` section.

    The points ``(s, p)`` are a Halton sequence (bases 2 and 3) over
    ``0 <= s < L_w`` (``L_w = wall_length / 2`` with ``half=True``: the
    arc of P1, which the swap of the ends ``P1 <-> P2`` maps onto the arc of
    P2, so every orbit is represented) and ``-1 <= p <= 1``, keeping those
    inside ``reduced_section_bounds``. ``(s, p)`` are area-preserving, so the
    seeds are uniform in phase-space measure at fixed ``(E, L)``: the fraction
    of seeds whose orbits are chaotic estimates the chaotic fraction of the
    energy-momentum surface. Deterministic (no random state).

    Returns:
        ``(count, 6)`` states from ``section_state`` (stick angle ``alpha = 0``).
    """
    require_x64()
    count = check_count("count", count, 0, "number of seeds", MAX_STORED_COUNT)
    offset = check_count("offset", offset, 0, "first index of the Halton sequence", MAX_STORED_COUNT)
    length = float(wall_length(scene)) * (0.5 if half else 1.0)
    chosen_s, chosen_p = [], []
    start = offset
    while len(chosen_s) < count:
        index = np.arange(start, start + 4 * count + 16)
        start = index[-1] + 1
        s = halton(index, 2) * length
        p = 2.0 * halton(index, 3) - 1.0
        bounds = np.asarray(reduced_section_bounds(scene, s, energy, angular_momentum))
        keep = (p > bounds[:, 0]) & (p < bounds[:, 1]) & (s > 1e-6 * length)
        chosen_s.extend(s[keep].tolist())
        chosen_p.extend(p[keep].tolist())
        if start > 10_000 * (count + 1):
            raise ValueError("no reachable section points at this (energy, angular_momentum)")
    s = jnp.asarray(chosen_s[:count])
    p = jnp.asarray(chosen_p[:count])
    return section_state(scene, s, p, energy, angular_momentum)


# -- the explorer's chart of the reduced section (StickInCircle.section_chart) ----------


def _circle_start(scene, s, p, invariants):
    states = section_state(scene, s, p, invariants["energy"], invariants["angular_momentum"])
    return states, contact_end(scene, jnp.nan_to_num(states))


def _circle_seeds(scene, count, invariants):
    states = section_seeds(scene, count, invariants["energy"], invariants["angular_momentum"])
    return states, contact_end(scene, states)


def _circle_points(scene, states, contacts):
    del contacts  # the reduced section finds the touching end from the state
    return reduced_section(scene, states)


def _circle_edge(scene, s, invariants):
    return np.asarray(reduced_section_bounds(scene, s, invariants["energy"], invariants["angular_momentum"]))


def _draw_circle_configuration(ax, scene, state0, orb, color):
    radius = float(scene.R)
    turn = np.linspace(0.0, 2.0 * np.pi, 300)
    ax.plot(radius * np.cos(turn), radius * np.sin(turn), color="k", lw=1.2)
    states = np.asarray(orb.state)
    path = np.concatenate([np.asarray(state0)[None, :2], states[:, :2]])
    ax.plot(path[:, 0], path[:, 1], color=color, lw=0.8, alpha=0.9)
    ends = np.asarray(end_points(scene, states))  # (n, 2, 2)
    for stick in ends:
        ax.plot(stick[:, 0], stick[:, 1], color="0.3", lw=0.9, alpha=0.55)
    ax.plot(*path[0], "o", color=color, ms=5)
    ax.set_xlim(-1.05 * radius, 1.05 * radius)
    ax.set_ylim(-1.05 * radius, 1.05 * radius)
    ax.set_xlabel("x (length)")
    ax.set_ylabel("y (length)")


# The axes of each section, for pictures (StickInCircle.section_axis_labels).
SECTION_AXIS_LABELS = {
    "paper": (r"$\phi_c = \arctan(p_y/p_x)$  (units of $\pi$)", r"$L_z = y\,p_x - x\,p_y$  (mass length$^2$/time)"),
    "reduced": (r"$s$: arc length along the rotating lens wall (length)", r"$p = \sqrt{M}\,v_t/\sqrt{2E}$"),
    "birkhoff": (r"$s$: arc length along the wall (length)", r"$\sin\chi = v_t/|v|$"),
}

CIRCLE_CHART = SectionChart(
    title="reduced section",
    axis_labels=SECTION_AXIS_LABELS["reduced"],
    invariant_symbols={"energy": "E", "angular_momentum": "L"},
    default_invariants=lambda scene: {"energy": 0.5, "angular_momentum": 0.0},
    x_range=lambda scene: (0.0, float(wall_length(scene))),
    edge=_circle_edge,
    start=_circle_start,
    seeds=_circle_seeds,
    points=_circle_points,
    draw_configuration=_draw_circle_configuration,
)
