"""Pictures of the scenes, with matplotlib.

Every ``draw_*`` function draws on a given ``Axes`` (a 3D one for
``draw_spiral_column``) and returns it; every ``*_figure`` function returns a
new ``matplotlib.figure.Figure`` (created without ``pyplot``, so it works with
any backend and needs no display; save it with ``fig.savefig``).

Lengths are in the units of the scene's ``R``; ``M`` is the stick's mass; time
is in the units of the states' velocities.

* ``draw_trajectory``: the configuration-space picture of the stick in a
  circle (the paper's Fig. 1): the circle, the path of the stick's centre, the
  stick at its contacts and the paper's rotating lens-shaped wall at one
  chosen contact.
* ``draw_ellipse_orbit``: the same for the stick in an ellipse, without the lens.
* ``draw_section``: section points of many orbits, coloured by orbit, with
  axes labelled for the chosen section (the stick in a circle's ``"paper"``,
  ``"reduced"`` or ``"birkhoff"``, or any section of the ``scene`` passed).
* ``draw_reduced_bounds``: the edge of the reachable region of the reduced
  section at given ``E`` and ``L``, and the lens corners.
* ``draw_spiral_column``: the spiral-column picture in 3D, the column surface
  ``r <= b(theta - alpha)`` swept along ``z = sqrt(I/M) alpha`` and the
  trajectory inside it.
* ``draw_walls_2d``, ``draw_wall_billiard``, ``draw_wall_flights``,
  ``draw_floor_section``, ``draw_floor_section_bounds``: the sticks between
  walls.
* ``plot_fli_map``: a map of fast Lyapunov indicators over a grid of starts
  (``jaxbill.fli_map``), with the axes labels the caller gives.
"""

from __future__ import annotations

import jax
import numpy as np
from jaxtyping import ArrayLike
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from mpl_toolkits.mplot3d import Axes3D

from jaxbill._engine.collision import Orbit
from jaxbill._scenes.circle.scene import StickInCircle
from jaxbill._scenes.circle.sections import (
    SECTION_AXIS_LABELS,
    half_corner_angle,
    reduced_section_bounds,
    wall_length,
)
from jaxbill._scenes.ellipse.sections import draw_ellipse_orbit
from jaxbill._scenes.protocols import HasSection
from jaxbill._scenes.walls.charts import draw_wall_billiard

__all__ = [
    "orbit_colors",
    "lens_outline",
    "draw_trajectory",
    "draw_ellipse_orbit",
    "draw_section",
    "draw_reduced_bounds",
    "unwrapped_angles",
    "draw_spiral_column",
    "trajectory_figure",
    "section_figure",
    "spiral_column_figure",
    "draw_walls_2d",
    "draw_wall_billiard",
    "draw_wall_flights",
    "draw_floor_section",
    "draw_floor_section_bounds",
    "plot_fli_map",
]


def _np(x):
    return np.asarray(x, dtype=np.float64)


def orbit_colors(count: int, cmap: str = "turbo"):
    """``count`` distinct colours, one per orbit, from a matplotlib colormap."""
    import matplotlib

    colormap = matplotlib.colormaps[cmap]
    if count <= 1:
        return [colormap(0.15)]
    return [colormap(0.05 + 0.9 * i / (count - 1)) for i in range(count)]


def lens_outline(scene: StickInCircle, alpha: float, points: int = 400) -> np.ndarray:
    """The lens-shaped wall ``r = b(theta - alpha)`` that the centre sees at stick angle ``alpha``.

    ``b(q) = -ell |cos q| + sqrt(R^2 - ell^2 sin^2 q)``: the intersection of the
    discs of radius ``R`` about ``-ell u`` and ``+ell u``. Returns ``(points, 2)``.
    """
    R, ell = float(scene.R), float(scene.ell)
    theta = np.linspace(0.0, 2.0 * np.pi, points)
    q = theta - alpha
    r = -ell * np.abs(np.cos(q)) + np.sqrt(R**2 - (ell * np.sin(q)) ** 2)
    return np.stack([r * np.cos(theta), r * np.sin(theta)], axis=-1)


def draw_trajectory(
    ax: Axes,
    scene: StickInCircle,
    state0: ArrayLike,
    orbit: Orbit,
    *,
    collisions: int | None = None,
    wall_at: int | None = 0,
    stick_every: int = 1,
    path_color: str = "tab:blue",
    stick_color: str = "0.55",
    wall_color: str = "tab:red",
):
    """The configuration-space trajectory of one orbit (the paper's Fig. 1).

    Args:
        ax: a 2D ``Axes``.
        scene: the ``StickInCircle``.
        state0: the orbit's initial state ``(6,)``.
        orbit: ``jb.orbit(scene, state0, n)`` (one orbit, not a batch).
        collisions: how many collisions to draw (default all).
        wall_at: index of the contact at which to draw the rotating lens wall
            (the region ``r <= b(theta - alpha)`` where the centre may be at that
            stick angle) with the centre on it; ``None`` for none.
        stick_every: draw the stick at every ``stick_every``-th contact.

    Draws the circle (black), the centre's straight flights (``path_color``),
    the stick at contacts (``stick_color``, the touching end dotted) and the
    wall (``wall_color``, dashed, with the stick at that contact in bold).
    """
    R, ell = float(scene.R), float(scene.ell)
    states = _np(orbit.state)
    if states.ndim != 2:
        raise ValueError("draw_trajectory draws one orbit: orbit.state must have shape (n, 6)")
    n = len(states) if collisions is None else min(collisions, len(states))
    states = states[:n]
    start = _np(state0)
    circle = np.linspace(0.0, 2.0 * np.pi, 400)
    ax.plot(R * np.cos(circle), R * np.sin(circle), color="k", lw=1.5)
    path = np.concatenate([start[None, :2], states[:, :2]])
    ax.plot(path[:, 0], path[:, 1], color=path_color, lw=0.9, label="path of the centre")
    ax.plot(*start[:2], "o", color=path_color, ms=4)
    ends = _end_points(scene, states)
    touching = np.argmin(np.abs(R**2 - np.sum(ends**2, axis=-1)), axis=-1)
    for j in range(0, n, max(1, stick_every)):
        ax.plot(ends[j, :, 0], ends[j, :, 1], color=stick_color, lw=0.7, alpha=0.7)
        ax.plot(*ends[j, touching[j]], ".", color=stick_color, ms=4)
    if wall_at is not None and n:
        j = wall_at % n
        lens = lens_outline(scene, float(states[j, 2]))
        ax.plot(lens[:, 0], lens[:, 1], "--", color=wall_color, lw=1.2, label=f"rotating wall at contact {j + 1}")
        ax.plot(ends[j, :, 0], ends[j, :, 1], color=wall_color, lw=2.5)
        ax.plot(*states[j, :2], "o", color=wall_color, ms=5)
    ax.set_aspect("equal")
    ax.set_xlim(-1.08 * R, 1.08 * R)
    ax.set_ylim(-1.08 * R, 1.08 * R)
    ax.set_xlabel("x (length)")
    ax.set_ylabel("y (length)")
    ax.set_title(f"R = {R:g}, ell = {ell:g}: {n} collisions")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=2, fontsize="small", frameon=False)
    return ax


def _end_points(scene, states):
    ell = float(scene.ell)
    u = np.stack([np.cos(states[..., 2]), np.sin(states[..., 2])], axis=-1)
    c = states[..., :2]
    return np.stack([c + ell * u, c - ell * u], axis=-2)


def _orbits_and_colors(points, colors):
    """Section points as ``(B, n, 2)`` and one colour per orbit (``colors``: None, one colour, or a list)."""
    pts = _np(points)
    if pts.ndim == 2:
        pts = pts[None]
    if pts.ndim != 3 or pts.shape[-1] != 2:
        raise ValueError(f"points must have shape (n, 2) or (B, n, 2); got {np.shape(points)}")
    if colors is None:
        colors = orbit_colors(len(pts))
    elif isinstance(colors, str) or (np.ndim(colors) == 1 and len(colors) in (3, 4) and not isinstance(colors[0], str)):
        colors = [colors] * len(pts)
    return pts, colors


def draw_section(
    ax: Axes,
    points: ArrayLike,
    kind: str = "paper",
    *,
    scene: HasSection | None = None,
    colors=None,
    markersize: float = 2.0,
    labels=None,
    title: str | None = None,
    rasterized: bool = True,
):
    """Section points of one or many orbits, coloured by orbit.

    Args:
        ax: a 2D ``Axes``.
        points: ``(n, 2)`` for one orbit or ``(B, n, 2)`` for ``B`` orbits, as
            returned by ``paper_section`` (``[L_z, phi_c]``, drawn with
            ``phi_c`` across and ``L_z`` up, the paper's axes),
            ``reduced_section``, ``birkhoff_section`` or a scene's
            ``section`` (``[s, p]``, drawn with ``s`` across). Non-finite
            points are skipped.
        kind: the section the points are in, which labels the axes: one of
            ``scene.sections``, or without ``scene`` one of the stick in a
            circle's, ``"paper"``, ``"reduced"`` or ``"birkhoff"``.
        scene: the scene the points come from: its ``section_axis_labels``
            label the axes (default: the stick in a circle's labels).
        colors: one colour per orbit (default ``orbit_colors(B)``), or one colour.
        markersize: the points' diameter in points (2: visible one by one at
            a screen's resolution; smaller for a dense cloud of many orbits).
        labels: optional legend label per orbit.
    """
    axis_labels = SECTION_AXIS_LABELS if scene is None else getattr(scene, "section_axis_labels", None)
    if axis_labels is None:
        raise ValueError(f"scene {type(scene).__name__} gives no section_axis_labels to label a section with")
    if kind not in axis_labels:
        raise ValueError(f"kind must be one of {tuple(axis_labels)}; got {kind!r}")
    pts, colors = _orbits_and_colors(points, colors)
    for i, orbit_points in enumerate(pts):
        if kind == "paper":
            x, y = orbit_points[:, 1], orbit_points[:, 0]
        else:
            x, y = orbit_points[:, 0], orbit_points[:, 1]
        ok = np.isfinite(x) & np.isfinite(y)
        ax.plot(
            x[ok],
            y[ok],
            linestyle="none",
            marker=".",
            markersize=markersize,
            markeredgewidth=0,
            color=colors[i % len(colors)],
            rasterized=rasterized,
            label=None if labels is None else labels[i],
        )
    xlabel, ylabel = axis_labels[kind]
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if kind == "paper":
        ax.set_xlim(-0.5, 0.5)
    if title is not None:
        ax.set_title(title)
    if labels is not None:
        ax.legend(loc="upper right", fontsize="small", markerscale=12, framealpha=0.8)
    return ax


def draw_reduced_bounds(
    ax: Axes, scene: StickInCircle, energy: float = 0.5, angular_momentum: float = 0.0, *, color="k"
):
    """Outline of the reduced section at ``(E, L)``: the edge ``p_min(s), p_max(s)`` and the corners.

    Sets the ``s`` limits to one turn of the wall. For the lens and the circle
    the edge is ``p = -1, 1``.
    """
    length = float(wall_length(scene))
    s = np.linspace(0.0, length, 800)
    bounds = _np(reduced_section_bounds(scene, s, energy, angular_momentum))
    ax.plot(s, bounds[:, 0], color=color, lw=0.8)
    ax.plot(s, bounds[:, 1], color=color, lw=0.8)
    if not scene.body_is_point:
        corner = 2.0 * float(scene.R) * float(half_corner_angle(scene))
        ax.axvline(corner, color=color, lw=0.6, ls=":")
    ax.set_xlim(0.0, length)
    return ax


def unwrapped_angles(state0: ArrayLike, orbit: Orbit) -> np.ndarray:
    """The stick angle at each collision, without the wrap into ``[-pi, pi)``: ``(n,)``.

    ``alpha_j = alpha_0 + sum_{i <= j} omega_{i-1} (t_i - t_{i-1})`` (the spin is
    constant in flight), so the total turning is exact, not guessed from wraps.
    """
    states = _np(orbit.state)
    t = _np(orbit.t)
    start = _np(state0)
    omegas = np.concatenate([[start[5]], states[:-1, 5]])
    dts = np.diff(np.concatenate([[0.0], t]))
    return start[2] + np.cumsum(omegas * dts)


def draw_spiral_column(
    ax3d: Axes3D,
    scene: StickInCircle,
    state0: ArrayLike,
    orbit: Orbit,
    *,
    collisions: int | None = None,
    surface_alpha: float = 0.12,
    path_color: str = "tab:blue",
):
    """The spiral-column picture: the point ``(x, y, z = sqrt(I/M) alpha)`` in straight flight inside the column.

    The column is ``r <= b(theta - alpha)`` swept along ``z``; its two creases
    (the lens corners, ``theta - alpha = +-pi/2``) are drawn as helices. The
    trajectory reflects specularly off the column surface.

    Args:
        ax3d: an ``Axes`` with ``projection="3d"``.
        scene: a ``StickInCircle`` with finite inertia (a rotor).
        state0, orbit: one orbit and its initial state.
        collisions: how many collisions to draw (default all).
    """
    if not scene.body_turns:
        raise ValueError("the spiral column needs a finite inertia and ell > 0 (the stick must turn)")
    states = _np(orbit.state)
    n = len(states) if collisions is None else min(collisions, len(states))
    pitch = float(np.sqrt(scene.inertia / scene.mass))
    alphas = np.concatenate([[float(_np(state0)[2])], unwrapped_angles(state0, orbit)[:n]])
    path = np.concatenate([_np(state0)[None, :2], states[:n, :2]])
    z = pitch * alphas
    R, ell = float(scene.R), float(scene.ell)
    q = np.linspace(0.0, 2.0 * np.pi, 90)
    a = np.linspace(alphas.min(), alphas.max(), 40)
    qq, aa = np.meshgrid(q, a)
    r = -ell * np.abs(np.cos(qq)) + np.sqrt(R**2 - (ell * np.sin(qq)) ** 2)
    theta = qq + aa
    ax3d.plot_surface(
        r * np.cos(theta),
        r * np.sin(theta),
        pitch * aa,
        color="tab:gray",
        alpha=surface_alpha,
        linewidth=0,
        antialiased=False,
        shade=True,
    )
    crease = np.sqrt(R**2 - ell**2)
    a_fine = np.linspace(alphas.min(), alphas.max(), 600)
    for side in (0.5 * np.pi, -0.5 * np.pi):
        ax3d.plot(crease * np.cos(a_fine + side), crease * np.sin(a_fine + side), pitch * a_fine, color="k", lw=0.8)
    ax3d.plot(path[:, 0], path[:, 1], z, color=path_color, lw=1.0)
    # matplotlib types zs as a scalar; an array of heights is what it draws with
    ax3d.scatter(path[1:, 0], path[1:, 1], z[1:], color=path_color, s=4)  # pyright: ignore[reportArgumentType]
    ax3d.set_xlabel("x (length)")
    ax3d.set_ylabel("y (length)")
    ax3d.set_zlabel(r"$z = \sqrt{I/M}\,\alpha$ (length)")
    height = max(float(z.max() - z.min()), 1e-9)
    ax3d.set_box_aspect((1.0, 1.0, min(3.0, max(0.5, height / (2.0 * R)))))
    ax3d.set_title(f"spiral column: R = {R:g}, ell = {ell:g}, {n} collisions")
    return ax3d


# -- whole figures -----------------------------------------------------------


def trajectory_figure(scene: StickInCircle, state0: ArrayLike, orbit: Orbit, **kwargs) -> Figure:
    """A ``Figure`` with ``draw_trajectory`` (the paper's Fig. 1)."""
    fig = Figure(figsize=(6, 6.6), layout="constrained")
    draw_trajectory(fig.add_subplot(), scene, state0, orbit, **kwargs)
    return fig


def section_figure(
    points: ArrayLike,
    kind: str = "paper",
    *,
    scene: StickInCircle | None = None,
    energy: float = 0.5,
    angular_momentum: float = 0.0,
    **kwargs,
) -> Figure:
    """A ``Figure`` with ``draw_section``; with a stick in a circle and its reduced/Birkhoff kind, its bounds too."""
    fig = Figure(figsize=(7, 5.5), layout="constrained")
    ax = fig.add_subplot()
    draw_section(ax, points, kind, scene=scene, **kwargs)
    if scene is not None and kind != "paper":
        draw_reduced_bounds(ax, scene, energy, angular_momentum)
    return fig


def spiral_column_figure(scene: StickInCircle, state0: ArrayLike, orbit: Orbit, **kwargs) -> Figure:
    """A ``Figure`` with ``draw_spiral_column``."""
    fig = Figure(figsize=(7, 7), layout="constrained")
    draw_spiral_column(fig.add_subplot(projection="3d"), scene, state0, orbit, **kwargs)
    return fig


# -- the stick between two flat walls ------------------------------------------
#
# ``draw_walls_2d``: the stick between the floor and the ceiling in the vertical
# plane (configuration space). ``draw_wall_billiard``: the paper's billiard
# picture, the walls ``b(theta)``, ``t(theta)`` drawn in lengths as ``(kappa theta,
# z)`` (``kappa = sqrt(I/M)``; the paper's ``(ell theta, z)`` for I = M ell^2),
# where every bounce is a specular reflection. ``draw_wall_flights``: an
# orbit's flights in that plane (straight in 2D and for L_z = 0, curved for
# L_z != 0). ``draw_floor_section`` and ``draw_floor_section_bounds``: the floor
# section ``(theta mod pi, p)`` of ``jaxbill._scenes.walls.sections`` and its edge.

_FLOOR_SECTION_LABELS = {
    "2d": r"$\theta$ mod $\pi$ (rad; stick flat at $\pi/2$)",
    "3d": r"polar angle $\theta$ of the stick (rad)",
}
_FLOOR_P_LABEL = r"$p = (I\dot\theta + M v_z\, dz/d\theta)/\sqrt{2 I E'}$"


def draw_walls_2d(
    ax: Axes,
    scene,
    state0: ArrayLike,
    orbit: Orbit,
    *,
    collisions: int | None = None,
    stick_every: int = 1,
    path_color: str = "tab:blue",
    stick_color: str = "0.45",
):
    """The 2D stick between the floor ``z = 0`` and the ceiling ``z = h``: centre path and stick at contacts.

    Args:
        ax: a 2D ``Axes``.
        scene: a ``StickBetweenWalls2D``.
        state0, orbit: one orbit and its initial state.
        collisions: how many collisions to draw (default all).
        stick_every: draw the stick at every ``stick_every``-th contact.

    The touching end is marked with a dot (red on the floor, green on the
    ceiling; both ends at a flat landing).
    """
    h, ell = float(scene.h), float(scene.ell)
    states = _np(orbit.state)
    n = len(states) if collisions is None else min(collisions, len(states))
    states, contacts = states[:n], _np(orbit.contact)[:n]
    start = _np(state0)
    path = np.concatenate([start[None, :2], states[:, :2]])
    ax.plot(path[:, 0], path[:, 1], color=path_color, lw=0.9, label="path of the centre")
    ax.plot(*start[:2], "o", color=path_color, ms=4)
    arm = ell * np.stack([np.sin(states[:, 2]), np.cos(states[:, 2])], axis=-1)
    ends = np.stack([states[:, :2] + arm, states[:, :2] - arm], axis=1)
    for j in range(0, n, max(1, stick_every)):
        ax.plot(ends[j, :, 0], ends[j, :, 1], color=stick_color, lw=1.0, alpha=0.8)
        for k in range(2):
            height = ends[j, k, 1]
            if abs(height) < 1e-9 * h:
                ax.plot(*ends[j, k], ".", color="tab:red", ms=5)
            elif abs(h - height) < 1e-9 * h:
                ax.plot(*ends[j, k], ".", color="tab:green", ms=5)
    lo = min(path[:, 0].min(), ends[..., 0].min()) - 0.2 * ell
    hi = max(path[:, 0].max(), ends[..., 0].max()) + 0.2 * ell
    for level in (0.0, h):
        ax.plot([lo, hi], [level, level], color="k", lw=1.5)
    ax.set_xlim(lo, hi)
    ax.set_ylim(-0.08 * h, 1.08 * h)
    ax.set_aspect("equal")
    ax.set_xlabel("x (length)")
    ax.set_ylabel("z (length)")
    ax.set_title(f"h = {h:g}, ell = {ell:g}: {n} collisions ({int(np.sum(contacts == 2))} flat landings)")
    return ax


def draw_wall_flights(
    ax: Axes,
    scene,
    state0: ArrayLike,
    orbit: Orbit,
    *,
    collisions: int | None = None,
    points_per_flight: int = 60,
    color: str = "tab:blue",
    walls: bool = True,
    margin: float = 0.15,
    label=None,
):
    """An orbit's flights in the ``(kappa theta, z)`` plane, with the walls.

    2D: ``theta`` unwrapped along the orbit, straight lines. 3D: ``theta`` the
    polar angle of ``u``; with ``L_z != 0`` the flights curve, and the
    potential barrier ``sin^2 theta = (I w_z)^2 / (2 I E')`` (dotted) keeps the
    stick away from the vertical.
    """
    from jaxbill._scenes.walls.sections import flight_paths, internal_energy_np

    states = _np(orbit.state)
    n = len(states) if collisions is None else min(collisions, len(states))
    short = jax.tree.map(np.asarray, orbit.first(n))
    paths = flight_paths(scene, state0, short, points_per_flight)
    kappa = float(np.sqrt(float(scene.inertia) / float(scene.mass)))
    flat = paths.reshape(-1, 2)
    ax.plot(flat[:, 0], flat[:, 1], color=color, lw=0.9, label=label)
    ax.plot(paths[:, -1, 0], paths[:, -1, 1], ".", color=color, ms=3.5)
    if walls:
        lo, hi = flat[:, 0].min() / kappa - margin, flat[:, 0].max() / kappa + margin
        if scene.state_size == 12:
            lo, hi = min(lo, 0.0), max(hi, np.pi)
        draw_wall_billiard(ax, scene, (lo, hi))
    if scene.state_size == 12:
        start = _np(state0)
        spin = float(scene.inertia) * start[11]
        energy = float(internal_energy_np(scene, start))
        if spin != 0.0:
            edge = np.arcsin(min(1.0, abs(spin) / np.sqrt(2.0 * float(scene.inertia) * energy)))
            for angle in (edge, np.pi - edge):
                ax.axvline(kappa * angle, color="tab:purple", lw=0.8, ls=":")
    return ax


def draw_floor_section(
    ax: Axes,
    points: ArrayLike,
    kind: str = "2d",
    *,
    colors=None,
    markersize: float = 0.6,
    labels=None,
    title: str | None = None,
    rasterized: bool = True,
):
    """Floor-section points ``(..., 2) = [theta, p]`` of one or many orbits (NaN skipped), ``theta`` across.

    ``kind``: ``"2d"`` (``floor_section``: ``theta mod pi``) or ``"3d"``
    (``reduced_wall_section``: the polar angle). ``points`` ``(n, 2)`` or
    ``(B, n, 2)``; ``colors``: one per orbit or one for all.
    """
    if kind not in _FLOOR_SECTION_LABELS:
        raise ValueError(f"kind must be one of {tuple(_FLOOR_SECTION_LABELS)}; got {kind!r}")
    pts, colors = _orbits_and_colors(points, colors)
    for i, orbit_points in enumerate(pts):
        ok = np.all(np.isfinite(orbit_points), axis=-1)
        ax.plot(
            orbit_points[ok, 0],
            orbit_points[ok, 1],
            linestyle="none",
            marker=".",
            markersize=markersize,
            markeredgewidth=0,
            color=colors[i % len(colors)],
            rasterized=rasterized,
            label=None if labels is None else labels[i],
        )
    ax.set_xlabel(_FLOOR_SECTION_LABELS[kind])
    ax.set_ylabel(_FLOOR_P_LABEL)
    ax.set_xlim(0.0, np.pi)
    if title is not None:
        ax.set_title(title)
    if labels is not None:
        ax.legend(loc="upper right", fontsize="small", markerscale=12, framealpha=0.8)
    return ax


def draw_floor_section_bounds(ax: Axes, scene, energy: float = 0.5, spin: float = 0.0, *, color="k"):
    """Edge ``p = +-floor_section_bound(theta)`` of the floor section at ``E'`` (and ``I w_z = spin``), and the kink."""
    from jaxbill._scenes.walls.sections import floor_section_bound

    theta = np.linspace(0.0, np.pi, 1601)
    bound = _np(floor_section_bound(scene, theta, energy, spin))
    ax.plot(theta, bound, color=color, lw=0.8)
    ax.plot(theta, -bound, color=color, lw=0.8)
    ax.axvline(0.5 * np.pi, color=color, lw=0.6, ls=":")
    ax.set_xlim(0.0, np.pi)
    return ax


def plot_fli_map(
    ax: Axes,
    values: ArrayLike,
    extent: tuple[float, float, float, float],
    *,
    xlabel: str,
    ylabel: str,
    cmap: str = "viridis",
    vmin: float | None = None,
    vmax: float | None = None,
    colorbar: bool = True,
    colorbar_label: str = "FLI",
    title: str | None = None,
):
    """An FLI map (``jaxbill.fli_map``) as an image, with the axes labels the caller gives.

    Args:
        ax: a 2D ``Axes``.
        values: ``(ny, nx)`` FLI values, ``values[i, j]`` at the ``i``-th ``y``
            and ``j``-th ``x`` of the grid (``np.meshgrid(x, y)``'s layout, the
            default ``indexing="xy"``), ``y`` increasing upwards. NaN pixels
            (invalid starts) are left blank.
        extent: ``(x_min, x_max, y_min, y_max)``, the grid's range in the
            section coordinates the labels name (pixel edges, as ``imshow``).
        xlabel, ylabel: the axes labels (the coordinates the grid was built
            in; the map itself does not know them).
        cmap, vmin, vmax: colours; by default the finite values' range.
        colorbar: add a colour bar labelled ``colorbar_label``.
        title: optional title.

    Returns:
        ``ax``. Regular orbits (``FLI ~ log n``) come out dark, chaotic ones
        (``FLI ~ lambda n``) bright; an Arnold web shows as bright lines.
    """
    image = _np(values)
    if image.ndim != 2:
        raise ValueError(f"values must be a 2D map (ny, nx); got shape {image.shape}")
    if len(extent) != 4:
        raise ValueError(f"extent must be (x_min, x_max, y_min, y_max); got {extent}")
    extent = (float(extent[0]), float(extent[1]), float(extent[2]), float(extent[3]))
    shown = ax.imshow(
        np.ma.masked_invalid(image),
        origin="lower",
        extent=extent,
        aspect="auto",
        cmap=cmap,
        vmin=vmin,
        vmax=vmax,
        interpolation="nearest",
    )
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title is not None:
        ax.set_title(title)
    if colorbar:
        ax.figure.colorbar(shown, ax=ax, label=colorbar_label)
    return ax
