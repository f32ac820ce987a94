"""Measures on section points: is an orbit a curve or an area, how much area, how many islands.

Plain NumPy on finished results (section points: ``jb.reduced_section``, ``jb.birkhoff_section``),
for checking claims about pictures with numbers:

* ``curve_thickness``: the local thickness of a point cloud. Around each point
  take its ``neighbours`` nearest points and fit a line (principal axes of
  their scatter); the thickness there is ``sqrt(lambda_min / lambda_max)`` of
  that scatter, the residual of the local line fit relative to the spread
  along it. Points on a smooth curve give a small number (it falls like the
  neighbourhood size times the curvature); points filling an area give
  ``O(1)`` (about 0.5 to 1). The median over the points is returned.
* ``covered_fraction``: the fraction of the reachable part of a reduced (or
  Birkhoff) section that a set of points visits, on a grid of cells. The
  ``(s, p)`` coordinates are area-preserving, so cell counts measure
  phase-space volume.
* ``count_islands``: the number of separate pieces a set of points forms on a
  grid (cells touching, diagonals included, are one piece): an orbit in a
  chain of ``k`` resonance islands draws ``k`` pieces.
* ``twin_divergence`` / ``is_chaotic`` / ``orbits_with_twins``: the dynamical test. Each orbit is
  run beside a twin whose velocity is turned by ``1e-11`` rad; on a torus the
  two drift apart linearly (to ``~1e-7`` after thousands of collisions), in a
  chaotic region exponentially, to order one. This is the classification the
  figures use: thin island chains, whose points can look like an area to
  ``curve_thickness``, are still told apart.
"""

from __future__ import annotations

import jax
import numpy as np
from jaxtyping import ArrayLike, Bool, Float

from jaxbill._engine.collision import Orbit
from jaxbill._engine.collision import orbit as _orbit
from jaxbill._scenes.circle.sections import reduced_section_bounds, wall_length
from jaxbill._scenes.protocols import Scene

CHAOTIC_DIVERGENCE = 1e-3  # twin_divergence above this: chaotic (a torus stays near delta * n)


def _finite_points(points) -> np.ndarray:
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    return pts[np.all(np.isfinite(pts), axis=1)]


def local_thickness(points, neighbours: int = 12, scale=None, samples: int | None = None) -> np.ndarray:
    """Thickness ``sqrt(lambda_min / lambda_max)`` of each point's neighbourhood, ``(n,)``.

    Args:
        points: ``(n, 2)``.
        neighbours: neighbourhood size (the point itself and its nearest others).
        scale: length of each axis used to make the axes comparable
            (default: each axis's standard deviation over the points).
        samples: if given, only this many points (evenly spaced along the
            orbit) are looked at, each against all others: ``(samples,)``.
    """
    pts = _finite_points(points)
    if len(pts) <= neighbours:
        raise ValueError(f"need more than {neighbours} finite points; got {len(pts)}")
    scale = pts.std(axis=0) if scale is None else np.asarray(scale, dtype=np.float64)
    pts = pts / np.where(scale > 0, scale, 1.0)
    queries = pts if samples is None or samples >= len(pts) else pts[np.linspace(0, len(pts) - 1, samples).astype(int)]
    out = np.empty(len(queries))
    chunk = max(1, 2_000_000 // len(pts))
    for start in range(0, len(queries), chunk):
        block = queries[start : start + chunk]
        d2 = np.sum((block[:, None, :] - pts[None, :, :]) ** 2, axis=-1)
        nearest = np.argpartition(d2, neighbours, axis=1)[:, :neighbours]
        hood = pts[nearest]  # (b, k, 2)
        hood = hood - hood.mean(axis=1, keepdims=True)
        cov = np.einsum("bki,bkj->bij", hood, hood) / neighbours
        eig = np.linalg.eigvalsh(cov)  # ascending
        out[start : start + chunk] = np.sqrt(np.maximum(eig[:, 0], 0.0) / np.maximum(eig[:, 1], 1e-300))
    return out


def curve_thickness(
    points: Float[ArrayLike, "*m 2"],
    neighbours: int = 12,
    scale: Float[ArrayLike, " 2"] | None = None,
    samples: int | None = 500,
) -> float:
    """Median local thickness (see ``local_thickness``): small for a curve, ``O(1)`` for an area.

    By default the median is taken over 500 points spread along the orbit
    (``samples=None``: all points).
    """
    return float(np.median(local_thickness(points, neighbours, scale, samples)))


def section_grid(scene, energy=0.5, angular_momentum=0.0, bins=(120, 80)):
    """Cells of the ``(s, p)`` plane and which are wholly reachable at ``(E, L)``.

    Returns ``(s_edges, p_edges, reachable)`` with ``reachable`` a boolean
    ``(bins[0], bins[1])`` array: cells whose four corners lie within
    ``reduced_section_bounds`` (cells cut by the edge are left out).
    """
    s_edges = np.linspace(0.0, float(wall_length(scene)), bins[0] + 1)
    p_edges = np.linspace(-1.0, 1.0, bins[1] + 1)
    bounds = np.asarray(reduced_section_bounds(scene, s_edges, energy, angular_momentum))
    lo = np.nan_to_num(bounds[:, 0], nan=np.inf)
    hi = np.nan_to_num(bounds[:, 1], nan=-np.inf)
    inside = (p_edges[None, :] >= lo[:, None]) & (p_edges[None, :] <= hi[:, None])  # (s edges, p edges)
    reachable = inside[:-1, :-1] & inside[1:, :-1] & inside[:-1, 1:] & inside[1:, 1:]
    return s_edges, p_edges, reachable


def occupancy(points, s_edges, p_edges) -> np.ndarray:
    """Boolean grid: which ``(s, p)`` cells hold at least one point."""
    pts = _finite_points(points)
    counts, _, _ = np.histogram2d(pts[:, 0], pts[:, 1], bins=[s_edges, p_edges])
    return counts > 0


def covered_fraction(
    scene: Scene,
    points: Float[ArrayLike, "*m 2"],
    energy: float = 0.5,
    angular_momentum: float = 0.0,
    bins: tuple[int, int] = (120, 80),
) -> float:
    """Fraction of the wholly reachable cells of the ``(s, p)`` section that ``points`` visit.

    ``points`` are reduced-section (or Birkhoff) points ``[s, p]`` of any shape
    ``(..., 2)``, all at the given ``(E, L)``.
    """
    s_edges, p_edges, reachable = section_grid(scene, energy, angular_momentum, bins)
    hit = occupancy(points, s_edges, p_edges)
    return float(np.sum(hit & reachable) / np.sum(reachable))


def count_islands(
    points: Float[ArrayLike, "*m 2"],
    bins: tuple[int, int] = (200, 200),
    extent: tuple[tuple[float, float], tuple[float, float]] | None = None,
) -> int:
    """Number of separate pieces the points form on a ``bins`` grid (8-connected cells).

    Args:
        points: ``(..., 2)``.
        bins: grid resolution; choose it so that consecutive points along one
            island's curve fall in touching cells while separate islands do not.
        extent: ``((x0, x1), (y0, y1))`` of the grid (default: the points' range).
    """
    pts = _finite_points(points)
    if extent is None:
        extent = ((pts[:, 0].min(), pts[:, 0].max()), (pts[:, 1].min(), pts[:, 1].max()))
    counts, _, _ = np.histogram2d(pts[:, 0], pts[:, 1], bins=bins, range=extent)
    return _count_components(counts > 0)


def _count_components(grid: np.ndarray) -> int:
    seen = np.zeros_like(grid, dtype=bool)
    pieces = 0
    nx, ny = grid.shape
    for i, j in zip(*np.nonzero(grid)):
        if seen[i, j]:
            continue
        pieces += 1
        stack = [(i, j)]
        seen[i, j] = True
        while stack:
            a, b = stack.pop()
            for da in (-1, 0, 1):
                for db in (-1, 0, 1):
                    x, y = a + da, b + db
                    if 0 <= x < nx and 0 <= y < ny and grid[x, y] and not seen[x, y]:
                        seen[x, y] = True
                        stack.append((x, y))
    return pieces


def twin_states(states0, delta: float = 1e-11) -> np.ndarray:
    """Start states of the twins for ``twin_divergence``: velocities turned by ``delta`` rad, ``(B, 6)``."""
    states0 = np.atleast_2d(np.asarray(states0, dtype=np.float64))
    c, s = np.cos(delta), np.sin(delta)
    twins = states0.copy()
    twins[:, 3] = c * states0[:, 3] - s * states0[:, 4]
    twins[:, 4] = s * states0[:, 3] + c * states0[:, 4]
    return twins


def divergence(scene, states, twin_states_, states0) -> np.ndarray:
    """Largest distance between the orbits ``states`` and their twins over the last tenth of the collisions.

    ``states`` and ``twin_states_`` are ``(B, n, 6)`` (``jb.orbit(...).state``);
    distances are ``|(x, y, vx, vy)_twin - (x, y, vx, vy)|`` in units of
    ``(R, |v_0|)``, ``|v_0|`` each orbit's start speed and ``R`` the scene's
    length ``sqrt(gap_scale)`` (the circle's radius; ``sqrt(ab)`` for the
    ellipse). Returns ``(B,)``.
    """
    states0 = np.atleast_2d(np.asarray(states0, dtype=np.float64))
    first, second = np.asarray(states), np.asarray(twin_states_)
    speed = np.hypot(states0[:, 3], states0[:, 4])[:, None]
    radius = float(np.max(np.sqrt(np.asarray(scene.gap_scale))))  # R for the circle, sqrt(ab) for the ellipse
    difference = np.sqrt(
        np.sum((first[..., 0:2] - second[..., 0:2]) ** 2, axis=-1) / radius**2
        + np.sum((first[..., 3:5] - second[..., 3:5]) ** 2, axis=-1) / speed**2
    )
    n = difference.shape[-1]
    tail = difference[:, -max(1, n // 10) :]
    return np.nan_to_num(np.max(tail, axis=1), nan=np.inf)


def orbits_with_twins(
    scene: Scene, states0: Float[ArrayLike, "B S"], n: int, delta: float = 1e-11
) -> tuple[Orbit, Float[np.ndarray, " B"]]:
    """Run orbits beside their slightly disturbed twins, in one batch: ``(the orbits, twin_divergence)``.

    What ``twin_divergence`` measures, with the orbits themselves kept (their
    section points, say) instead of run a second time.

    Args:
        scene: a planar stick ``[x, y, alpha, vx, vy, omega]`` in a table
            (``StickInCircle``, ``StickInEllipse``).
        states0: ``(B, 6)`` start states.
        n: number of collisions.
        delta: the angle (radians) by which each twin's velocity is turned.

    Returns:
        The ``Orbit`` of the ``B`` starts (``state`` ``(B, n, 6)``) and, per
        orbit, the twin divergence ``(B,)`` (see ``twin_divergence``).
    """
    states0 = np.atleast_2d(np.asarray(states0, dtype=np.float64))
    both = jax.device_get(_orbit(scene, np.concatenate([states0, twin_states(states0, delta)]), n))
    count = len(states0)
    orbits = jax.tree_util.tree_map(lambda a: a[:count], both)
    return orbits, divergence(scene, both.state[:count], both.state[count:], states0)


def twin_divergence(
    scene: Scene, states0: Float[ArrayLike, "B S"], n: int, delta: float = 1e-11
) -> Float[np.ndarray, " B"]:
    """How far each orbit and its slightly disturbed twin end up apart after ``n`` collisions.

    The twin starts from the same position with the velocity turned by
    ``delta`` radians (same speed: same energy for a free stick; the angular
    momentum changes by ``O(delta)``). Returns, per orbit, the largest distance
    ``|(x, y, vx, vy)_twin - (x, y, vx, vy)|`` over the last tenth of the
    collisions, in units of ``(R, |v_0|)``: ``~delta * n`` on a torus, ``O(1)``
    for a chaotic orbit; above ``CHAOTIC_DIVERGENCE`` counts as chaotic
    (``is_chaotic``). ``orbits_with_twins`` returns the orbits too.

    Args:
        scene: a planar stick ``[x, y, alpha, vx, vy, omega]`` in a table
            (``StickInCircle``, ``StickInEllipse``; the walls have
            ``wall_twin_divergence``).
        states0: ``(B, 6)`` start states.
        n: number of collisions (a few thousand tells chaos with Lyapunov
            exponents above ``~0.01`` per collision).
        delta: the angle (radians) by which each twin's velocity is turned.
    """
    return orbits_with_twins(scene, states0, n, delta)[1]


def is_chaotic(
    scene: Scene, states0: Float[ArrayLike, "B S"], n: int, threshold: float = CHAOTIC_DIVERGENCE
) -> Bool[np.ndarray, " B"]:
    """``twin_divergence(scene, states0, n) > threshold`` (default ``1e-3``): ``(B,)`` booleans."""
    return twin_divergence(scene, states0, n) > threshold
