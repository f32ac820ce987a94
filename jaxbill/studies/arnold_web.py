"""The Arnold web of a stick in a slightly eccentric ellipse, and the diffusion of ``L`` along it.

The setting. In the circle of radius ``R`` the total
angular momentum ``L`` is conserved and the motion of a stick with
``I = M ell^2`` at ``ell = 1.9``, ``R = 2`` is mostly regular: at fixed energy
``E`` the collision map lives on a four-dimensional section ``(s, p, alpha, L)``
(``s, p`` the reduced section, ``reduced_section``; ``alpha`` the cyclic
rotation angle, here the stick angle), ``L`` is a constant and a regular orbit
lies on a 2-torus of the map with two frequencies per collision:

* ``nu1``: the rotation number of the reduced map. At ``ell = 1.9`` the
  reduced section holds two copies of one family of closed curves, one round
  an elliptic point on each end's arc (``s = Lw/4`` and ``3 Lw/4``, ``Lw`` the
  wall length), and an orbit hops between the copies. Folding ``s`` modulo
  ``Lw/2`` (the relabelling of the ends) leaves one family of loops; ``nu1`` is
  the mean turn per collision round its centre, in ``[0, 1)``
  (``loop_angle``). For the point particle in a circle (``ell = 0``) the curves
  are ``p = const`` and the angle is the contact's polar angle ``s / R``.
* ``nu2``: the precession of the stick angle, ``<Delta alpha> / 2 pi`` per
  collision.

Deforming the circle into the ellipse ``a = R (1 + eps)``, ``b = R (1 - eps)``
adds the wall displacement ``delta r = eps R cos(2 Phi)`` (``Phi`` the contact's
polar angle ``= alpha + beta(s) (+ pi)``) at first order; it couples the
frequencies through the harmonics ``exp(i (k1 theta + 2 alpha))`` only, so the
first-order resonances are ``k1 nu1 + 2 nu2 = k3``, and ``k1 nu1 + 2 m nu2 =
k3`` at order ``eps^m``; odd ``k2`` are forbidden by the symmetry ``alpha ->
alpha + pi`` of both the stick and the ellipse (``resonances``).

Maps are drawn over the plane (``p`` on the line ``s = Lw/4``, ``L``): every
circle torus at ``L`` crosses the line ``s = Lw/4`` twice (above and below its
centre), so the map is a mirror image of itself about ``p ~ 0`` and each
resonance appears twice. The starts (``web_grid``) have the touching end at
the polar angle ``Phi = 0``, on the major axis, where the ellipse lies outside
the circle: the same states are valid starts for every ``eps >= 0``.

Functions here are numpy / ``jax.numpy`` on top of the public ``jaxbill`` API
(the modules behind ``jaxbill``'s names, imported directly, never the package itself).
"""

from __future__ import annotations

import math
import pathlib
from dataclasses import dataclass

import numpy as np
from jax.typing import ArrayLike
from jaxtyping import Float

from jaxbill._engine.collision import orbit
from jaxbill._scenes.circle.scene import StickInCircle
from jaxbill._scenes.circle.sections import reduced_section, section_state, wall_length
from jaxbill._scenes.ellipse.scene import StickInEllipse
from jaxbill._scenes.protocols import Scene, angular_momentum

__all__ = [
    "ellipse_scene",
    "web_grid",
    "web_starts",
    "weighted_birkhoff_mean",
    "loop_angle",
    "torus_frequencies",
    "resonances",
    "resonance_value",
    "resonance_crossings",
    "fli_ridges",
    "ridge_offsets",
    "RidgeOffsets",
    "TorusFrequencies",
    "frequencies_from_orbit",
    "circle_scene",
    "centre_line_s",
    "values_at_times",
    "spread_against_time",
    "fit_power_law",
    "torus_label_path",
    "arnold_web_figure",
    "load_data",
    "trusted_frequencies",
    "predicted_lines",
    "draw_web",
    "DATA_PATH",
]

DATA_PATH = pathlib.Path(__file__).resolve().parents[2] / "notebooks" / "data" / "arnold_web.npz"
"""Where ``notebooks/data/make_arnold_web_data.py`` writes the stored maps and runs."""


# --------------------------------------------------------------------------- scenes and starts


def ellipse_scene(R: float, ell: float, eps: float, mass: float = 1.0, inertia: float | None = None):
    """The stick in the ellipse ``a = R (1 + eps)``, ``b = R (1 - eps)`` (``eps = 0``: the circle of radius ``R``).

    Args:
        R: mean radius (length). ell: half-length of the stick (length).
        eps: eccentricity parameter, ``0 <= eps < 1`` (dimensionless).
        mass, inertia: as ``StickInEllipse`` (``inertia=None``: ``mass * ell**2``).

    Returns:
        ``StickInEllipse``. At ``eps = 0`` it is the circle, computed by the
        ellipse's code (its orbits agree with ``StickInCircle``'s to rounding,
        and ``L`` is conserved to rounding).
    """
    return StickInEllipse(a=R * (1.0 + eps), b=R * (1.0 - eps), ell=ell, mass=mass, inertia=inertia)


def circle_scene(R: float, ell: float, mass: float = 1.0, inertia: float | None = None):
    """``StickInCircle`` with the same parameters: the scene whose reduced section labels the tori."""
    return StickInCircle(R=R, ell=ell, mass=mass, inertia=inertia)


def centre_line_s(circle) -> float:
    """``s0 = Lw / 4``: the middle of end P1's arc of the reduced section (``beta = 0``), length units."""
    return float(wall_length(circle)) / 4.0


def web_starts(circle, p, L, energy: float):
    """Starts at the reduced-section points ``(s0, p)`` with angular momenta ``L``, contact at ``(R, 0)``.

    Each start is the circle's state just after a collision of end P1 at the
    reduced-section point ``(s0, p)`` (``s0 = Lw/4``, where P1 meets the wall
    along the stick, ``beta = 0``) with angular momentum ``L``, turned so that
    the contact is at the polar angle ``Phi = 0`` (the stick along the x axis).
    For the ellipse of ``ellipse_scene`` (``a >= R`` on the x axis; for
    ``ell = 1.9``, ``R = 2`` the other end stays within 45 degrees of the axis,
    where the ellipse is outside the circle too) that state is inside the table
    (on the wall at ``eps = 0``) and moving inwards: a valid start for every ``eps``.

    Args:
        circle: a ``StickInCircle`` (finite inertia, ``ell > 0``).
        p, L: arrays broadcast together: tangential momentum (units of
            ``sqrt(2 M E)``) and angular momentum (mass length^2 / time).
        energy: ``E``.

    Returns:
        ``(..., 6)`` numpy array, NaN where ``(s0, p)`` is not reachable at ``(E, L)``.
    """
    s0 = centre_line_s(circle)
    beta = s0 / float(circle.R) - math.acos(float(circle.ell) / float(circle.R))  # = 0 up to rounding
    p, L = np.broadcast_arrays(np.asarray(p, dtype=np.float64), np.asarray(L, dtype=np.float64))
    return np.asarray(section_state(circle, np.full(p.shape, s0), p, energy, L, rotation=-beta))


def web_grid(circle, p, L, energy: float):
    """Starts over the plane (``p`` on the line ``s = Lw/4``) x ``L`` at energy ``E`` (``web_starts`` on a mesh).

    Args:
        circle: a ``StickInCircle`` (finite inertia, ``ell > 0``).
        p: ``(nx,)`` tangential momenta (units of ``sqrt(2 M E)``).
        L: ``(ny,)`` angular momenta (mass length^2 / time).
        energy: ``E``.

    Returns:
        ``(ny, nx, 6)`` numpy array (``np.meshgrid(p, L)``'s layout, as
        ``jaxbill.plotting.plot_fli_map`` wants), NaN where ``(s0, p)`` is not
        reachable at ``(E, L)``.
    """
    pp, ll = np.meshgrid(np.asarray(p, dtype=np.float64), np.asarray(L, dtype=np.float64))
    return web_starts(circle, pp, ll, energy)


# --------------------------------------------------------------------------- frequencies


def weighted_birkhoff_mean(values, axis: int = -1):
    """The weighted Birkhoff average of ``values`` along ``axis`` (Das, Sander, Yorke 2017).

    The weights ``w(t) = exp(-1 / (t (1 - t)))``, ``t = (j + 1/2) / N``, normalised
    to sum 1, vanish with all derivatives at both ends: for a smooth function
    sampled along a quasi-periodic orbit (a torus) the error falls faster than
    any power of ``N`` instead of as ``1/N``; along a chaotic orbit it falls as
    slowly as the plain mean's.

    Args:
        values: ``(..., N, ...)`` samples ``f(x_j)`` along an orbit.
        axis: the axis of the orbit's steps.

    Returns:
        The average, ``values`` with ``axis`` removed.
    """
    values = np.asarray(values, dtype=np.float64)
    n = values.shape[axis]
    t = (np.arange(n) + 0.5) / n
    w = np.exp(-1.0 / (t * (1.0 - t)))
    w /= w.sum()
    return np.tensordot(np.moveaxis(values, axis, -1), w, axes=([-1], [0]))


def loop_angle(circle, states):
    """The angle of each collision round its orbit's centre in the folded reduced section (radians).

    For a stick (``ell > 0``) the reduced section ``(s, p)`` is folded onto the
    half wall, ``s mod (Lw / 2)``, and each orbit's points are measured round
    their own centroid, ``s`` and ``p`` scaled by the orbit's spreads:
    ``theta = atan2((p - <p>) / sd_p, (s - <s>) / sd_s)``. Its turn per collision
    is the same for any centre inside a loop (a winding number). For the point
    (``ell = 0``) the angle is the contact's polar angle ``s / R``.

    Args:
        circle: the ``StickInCircle`` whose section labels the tori.
        states: ``(..., n, 6)`` states at ``n`` successive collisions of a
            circle orbit (``orbit(...).state``).

    Returns:
        ``(..., n)`` angles in ``(-pi, pi]``.
    """
    sp = np.asarray(reduced_section(circle, states))
    s, p = sp[..., 0], sp[..., 1]
    if float(circle.ell) == 0.0:
        return np.angle(np.exp(1j * s / float(circle.R)))
    half = float(wall_length(circle)) / 2.0
    s = np.remainder(s, half)
    ds = s - s.mean(axis=-1, keepdims=True)
    dp = p - p.mean(axis=-1, keepdims=True)
    sd_s = np.sqrt((ds**2).mean(axis=-1, keepdims=True))
    sd_p = np.sqrt((dp**2).mean(axis=-1, keepdims=True))
    return np.arctan2(dp / sd_p, ds / sd_s)


@dataclass(frozen=True)
class TorusFrequencies:
    """Frequencies per collision of circle orbits (what ``torus_frequencies`` returns).

    Attributes:
        nu1: ``(...)`` rotation number of the (folded) reduced map, in ``[0, 1)``.
        nu2: ``(...)`` precession of the stick angle, ``<Delta alpha> / (2 pi)``.
        spread: ``(...)`` ``max`` over ``nu1, nu2`` of the difference between
            the estimates from the orbit's first and second halves: ``~1e-8`` or
            less on a torus, ``>~1e-4`` on a chaotic orbit.
    """

    nu1: np.ndarray
    nu2: np.ndarray
    spread: np.ndarray


def frequencies_from_orbit(circle, state0, states) -> TorusFrequencies:
    """``nu1``, ``nu2`` of circle orbits from their collisions (weighted Birkhoff averages).

    Args:
        circle: the ``StickInCircle`` of the orbits.
        state0: ``(..., 6)`` the starts (a collision state, e.g. from ``web_grid``).
        states: ``(..., n, 6)`` the next ``n`` collisions (``orbit(circle, state0, n).state``),
            (the engine wraps the stick angle into ``(-pi, pi]``; each
            collision's turn is taken in ``(-pi, pi]``, so it must be smaller
            than half a turn).

    Returns:
        ``TorusFrequencies`` of shape ``(...)``. Turns per collision are taken
        modulo one turn into ``[0, 2 pi)`` for ``nu1``, as increments of the
        stick angle in ``(-pi, pi]`` for ``nu2``.
    """
    state0 = np.asarray(state0, dtype=np.float64)
    states = np.asarray(states, dtype=np.float64)
    full = np.concatenate([state0[..., None, :], states], axis=-2)
    theta = loop_angle(circle, full)
    d_theta = np.remainder(np.diff(theta, axis=-1), 2.0 * np.pi) / (2.0 * np.pi)
    # The engine keeps alpha in (-pi, pi]; a collision turns the stick by much less than pi.
    d_alpha = (np.remainder(np.diff(full[..., 2], axis=-1) + np.pi, 2.0 * np.pi) - np.pi) / (2.0 * np.pi)
    n = d_theta.shape[-1]
    h = n // 2
    nu1 = weighted_birkhoff_mean(d_theta)
    nu2 = weighted_birkhoff_mean(d_alpha)
    spread = np.maximum(
        np.abs(weighted_birkhoff_mean(d_theta[..., :h]) - weighted_birkhoff_mean(d_theta[..., h:])),
        np.abs(weighted_birkhoff_mean(d_alpha[..., :h]) - weighted_birkhoff_mean(d_alpha[..., h:])),
    )
    return TorusFrequencies(nu1=nu1, nu2=nu2, spread=spread)


def torus_frequencies(
    circle: Scene, states0: Float[ArrayLike, "*grid 6"], n: int = 2000, batch: int = 512
) -> TorusFrequencies:
    """``nu1``, ``nu2`` per collision of the circle orbits from ``states0`` (see the module docstring).

    Runs ``n`` collisions of each orbit (``orbit``, in batches of ``batch``
    orbits so that memory stays at ``batch * n * 48`` bytes) and applies
    ``frequencies_from_orbit``. NaN starts give NaN.

    Args:
        circle: a ``StickInCircle`` (or the ``eps = 0`` ellipse for ``nu2``;
            ``nu1`` needs the circle's reduced section, so pass the circle).
        states0: ``(..., 6)`` starts at collisions (``web_grid``).
        n: collisions per orbit (the estimates on a torus converge fast with
            ``n``: see ``weighted_birkhoff_mean``).
        batch: orbits per call of ``orbit``.

    Returns:
        ``TorusFrequencies`` of shape ``states0.shape[:-1]``.
    """
    states0 = np.asarray(states0, dtype=np.float64)
    shape = states0.shape[:-1]
    flat = states0.reshape(-1, states0.shape[-1])
    ok = np.all(np.isfinite(flat), axis=-1)
    out = np.full((3, flat.shape[0]), np.nan)
    idx = np.flatnonzero(ok)
    for i in range(0, idx.size, batch):
        sel = idx[i : i + batch]
        orb = orbit(circle, flat[sel], n)
        f = frequencies_from_orbit(circle, flat[sel], np.asarray(orb.state))
        out[:, sel] = f.nu1, f.nu2, f.spread
    return TorusFrequencies(*(o.reshape(shape) for o in out))


# --------------------------------------------------------------------------- resonances


def resonances(
    max_order: int,
    k2_values: tuple[int, ...] = (2,),
    nu1_range: tuple[float, float] = (0.0, 1.0),
    nu2_range: tuple[float, float] = (-1.0, 1.0),
):
    """The harmonics ``(k1, k2)`` whose resonance lines ``k1 nu1 + k2 nu2 = k3`` cross a box of frequencies.

    A harmonic ``exp(i (k1 theta + k2 alpha))`` of the perturbation is
    resonant where ``k1 nu1 + k2 nu2`` is an integer ``k3``. The ellipse's
    wall at first order in ``eps`` has ``k2 = 2`` only (``k2 = 2 m`` at order
    ``eps^m``; see the module docstring), so the default lists those. Two
    harmonics with proportional ``(k1, k2, k3)`` draw the same line (e.g.
    ``(14, 2, 6)`` and ``(7, 1, 3)``); each line is listed once, by its
    lowest-order harmonic among ``k2_values``.

    Args:
        max_order: largest ``|k1| + |k2|`` (the harmonic's order).
        k2_values: the ``k2`` to include (positive integers).
        nu1_range, nu2_range: the box ``[min, max]`` of the frequencies where a
            line must pass (its ``k3`` is chosen so).

    Returns:
        list of integer triples ``(k1, k2, k3)``, sorted by order ``|k1| + |k2|``
        then ``(k1, k2, k3)``.
    """
    lines = {}
    corners = [(a, b) for a in nu1_range for b in nu2_range]
    for k2 in sorted(k2_values):
        for k1 in range(-(max_order - abs(k2)), max_order - abs(k2) + 1):
            if k2 == 0 and k1 <= 0:
                continue
            values = [k1 * a + k2 * b for a, b in corners]
            lo, hi = min(values), max(values)
            for k3 in range(math.ceil(lo), math.floor(hi) + 1):
                g = math.gcd(math.gcd(abs(k1), abs(k2)), abs(k3))
                key = (k1 // g, k2 // g, k3 // g)
                order = abs(k1) + abs(k2)
                if key not in lines or order < abs(lines[key][0]) + abs(lines[key][1]):
                    lines[key] = (k1, k2, k3)
    return sorted(lines.values(), key=lambda k: (abs(k[0]) + abs(k[1]), k))


def resonance_value(k, nu1, nu2):
    """``k1 nu1 + k2 nu2 - k3``: zero on the resonance ``k = (k1, k2, k3)``; arrays broadcast."""
    k1, k2, k3 = k
    return k1 * np.asarray(nu1) + k2 * np.asarray(nu2) - k3


def resonance_crossings(k, coord, nu1, nu2, valid=None, axis: int = 0):
    """Where the resonance ``k`` crosses each line of a grid: the sign changes of ``resonance_value``.

    Args:
        k: ``(k1, k2, k3)``.
        coord: the grid's coordinate along ``axis`` (``(ny,)`` the ``L`` values
            for ``axis=0``: each column is scanned along ``L``; ``(nx,)`` the
            ``p`` values for ``axis=1``: each row along ``p``).
        nu1, nu2: ``(ny, nx)`` frequencies on the grid (NaN: no torus).
        valid: optional ``(ny, nx)`` bool: pixels whose frequencies are trusted
            (e.g. ``spread < 1e-8``); a crossing needs both neighbours valid.
        axis: the grid axis scanned.

    Returns:
        list (one per column for ``axis=0``, per row for ``axis=1``) of 1D
        arrays of the crossings, linear interpolation between two pixels.
    """
    f = resonance_value(k, nu1, nu2)
    ok = np.isfinite(f) if valid is None else (np.isfinite(f) & valid)
    if axis == 0:
        f, ok = f.T, ok.T
    coord = np.asarray(coord)
    out = []
    for fi, oki in zip(f, ok):
        a, b = fi[:-1], fi[1:]
        with np.errstate(invalid="ignore"):
            # a zero on a pixel counts once (as the start of the pair it opens)
            change = ((a <= 0) & (b > 0)) | ((a >= 0) & (b < 0))
            c = oki[:-1] & oki[1:] & change & (np.abs(a - b) < 0.25)
        j = np.flatnonzero(c)
        out.append(coord[j] + (coord[j + 1] - coord[j]) * a[j] / (a[j] - b[j]))
    return out


# --------------------------------------------------------------------------- ridges


def fli_ridges(fli, coord, contrast: float = 0.5, width: int = 2, axis: int = 0):
    """The ridges of an FLI map: along each grid line, the local maxima that stand above their surroundings.

    A pixel is a ridge point when it is the largest within ``width`` pixels on
    each side along ``axis`` and exceeds the median of the ``4 width + 1``
    pixels around it by ``contrast`` (FLI units: a factor ``e^contrast`` in
    tangent-vector growth). A ridge crossed along ``axis`` is found; one
    running along ``axis`` is not (scan the other axis for those).

    Args:
        fli: ``(ny, nx)`` FLI map (NaN pixels are never ridges).
        coord: the coordinate along ``axis`` (``(ny,)`` for ``axis=0``).
        contrast: the least height above the local median.
        width: half-width of the local-maximum test, in pixels.
        axis: ``0``: scan each column (ridges that run across ``L``, e.g. nearly
            horizontal lines in a ``(p, L)`` map); ``1``: scan each row.

    Returns:
        list (one per column / row) of 1D arrays of ridge positions in
        ``coord`` units (a parabola through the peak and its neighbours places
        it between pixels).
    """
    fli = np.asarray(fli, dtype=np.float64)
    if axis == 0:
        fli = fli.T
    coord = np.asarray(coord, dtype=np.float64)
    n = fli.shape[1]
    out = []
    for r in fli:
        found = []
        for j in range(2 * width, n - 2 * width):
            win = r[j - width : j + width + 1]
            wide = r[j - 2 * width : j + 2 * width + 1]
            if not np.all(np.isfinite(wide)) or r[j] < np.max(win):
                continue
            if r[j] - np.median(wide) < contrast:
                continue
            a, b, c = r[j - 1], r[j], r[j + 1]
            den = a - 2.0 * b + c
            shift = 0.5 * (a - c) / den if den < 0 else 0.0
            found.append(coord[j] + shift * (coord[j + 1] - coord[j]))
        out.append(np.asarray(found))
    return out


@dataclass(frozen=True)
class RidgeOffsets:
    """Observed ridges round each predicted crossing of a resonance (what ``ridge_offsets`` returns).

    Attributes:
        line: ``(K,)`` the predicted crossings (map units).
        above, below: ``(K,)`` signed offset ``x_ridge - x_line`` of the nearest
            ridge on each side within the window (``above >= 0``, ``below <= 0``;
            NaN when there is none).
        nearest: ``(K,)`` ``min(|above|, |below|)`` (NaN when neither).
    """

    line: np.ndarray
    above: np.ndarray
    below: np.ndarray

    @property
    def nearest(self) -> np.ndarray:
        return np.fmin(np.abs(self.above), np.abs(self.below))

    @property
    def missed(self) -> int:
        """Predicted crossings with no ridge on either side within the window."""
        return int(np.sum(~np.isfinite(self.nearest)))


def ridge_offsets(ridges, crossings, window: float) -> RidgeOffsets:
    """Match observed FLI ridges to predicted resonance crossings along the same grid lines.

    A thin resonance shows as one ridge on its line; a resolved one as a band
    whose edges (the chaotic layer along the separatrices) are two ridges, one
    on each side, about a half-width away, with the line (the exact resonance,
    the band's centre) between them.

    Args:
        ridges: list (per grid line) of ridge positions (``fli_ridges``).
        crossings: list (per grid line, same scan) of the predicted crossings of one
            resonance (``resonance_crossings``).
        window: the farthest a ridge may be from the line to be matched (map units).

    Returns:
        ``RidgeOffsets`` over all the predicted crossings.
    """
    line, above, below = [], [], []
    for r, c in zip(ridges, crossings):
        r = np.asarray(r)
        for xc in c:
            d = r - xc
            up = d[(d >= 0) & (d <= window)]
            down = d[(d < 0) & (d >= -window)]
            line.append(xc)
            above.append(up.min() if up.size else np.nan)
            below.append(down.max() if down.size else np.nan)
    return RidgeOffsets(np.asarray(line), np.asarray(above), np.asarray(below))


# --------------------------------------------------------------------------- diffusion


def values_at_times(t, values, times):
    """Each orbit's value at common times: the last recorded value at or before each time.

    Args:
        t: ``(B, K)`` increasing record times of each orbit (collision times).
        values: ``(B, K)`` the quantity right after each recorded collision
            (``L`` changes only at collisions, so it is constant until the next).
        times: ``(T,)`` common times.

    Returns:
        ``(B, T)``; NaN where an orbit has no record at or before the time, or
        its records end before it (the orbit was not run that long).
    """
    t = np.asarray(t)
    values = np.asarray(values)
    out = np.full((t.shape[0], len(times)), np.nan)
    for b in range(t.shape[0]):
        j = np.searchsorted(t[b], times, side="right") - 1
        ok = (j >= 0) & (np.asarray(times) <= t[b, -1])
        out[b, ok] = values[b, j[ok]]
    return out


def spread_against_time(t, L, L0, times, n_sub: int = 8):
    """``<(L - L0)^2>`` over an ensemble at common times, with an error bar from sub-ensembles.

    Every orbit counts at every time (a common time window, see the physics
    notes), not at a common collision count.

    Args:
        t: ``(B, K)`` record times (``run(..., record="states", every=...).t``).
        L: ``(B, K)`` angular momentum after those collisions.
        L0: ``(B,)`` the starts' angular momenta.
        times: ``(T,)`` common times (within every orbit's run).
        n_sub: number of independent sub-ensembles (orbits dealt in turn).

    Returns:
        ``(msd, err)``: ``(T,)`` the mean square change and the standard error
        of that mean from the scatter of the ``n_sub`` sub-ensemble means.
    """
    L_t = values_at_times(t, L, times)
    sq = (L_t - np.asarray(L0)[:, None]) ** 2
    msd = np.nanmean(sq, axis=0)
    subs = np.stack([np.nanmean(sq[i::n_sub], axis=0) for i in range(n_sub)])
    err = np.std(subs, axis=0, ddof=1) / math.sqrt(n_sub)
    return msd, err


def fit_power_law(x, y, err=None):
    """Least-squares fit of ``log y = log A + g log x`` (weights ``y / err`` when given).

    Returns:
        ``(A, g, sd_logA, sd_g)``: the prefactor, the exponent and their standard errors
        (from the residual scatter when ``err`` is None).
    """
    x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    ok = (x > 0) & (y > 0) & np.isfinite(y)
    lx, ly = np.log(x[ok]), np.log(y[ok])
    w = np.ones_like(lx) if err is None else (y[ok] / np.asarray(err)[ok]) ** 2
    a = np.stack([np.ones_like(lx), lx], axis=1)
    aw = a * w[:, None]
    cov = np.linalg.inv(a.T @ aw)
    coef = cov @ (aw.T @ ly)
    res = ly - a @ coef
    dof = max(len(lx) - 2, 1)
    scale = (res**2 * w).sum() / dof if err is None else max(1.0, (res**2 * w).sum() / dof)
    sd = np.sqrt(np.diag(cov) * scale)
    return math.exp(coef[0]), coef[1], sd[0], sd[1]


def torus_label_path(circle, states, window: int, s_tol: float = 0.03):
    """A slowly varying torus label ``p*`` along an orbit of a perturbed circle, and its ``L``.

    Over each window of ``window`` collisions, ``p*`` is the largest ``p`` among
    the collisions whose folded ``s`` lies within ``s_tol`` (length) of
    ``s0 = Lw/4``: where the orbit's current loop crosses the map's line above
    its centre, the map's ``x`` coordinate. ``L`` is the window's mean.

    Args:
        circle: the ``StickInCircle`` whose section labels the tori.
        states: ``(n, 6)`` collisions of one orbit (e.g. in an ellipse).
        window: collisions per window (a few loop periods, ``>~ 20 / min(nu1, 1 - nu1)``).
        s_tol: half-width of the strip round the line.

    Returns:
        ``(p_star, L)``: ``(n // window,)`` each (NaN for a window with no point in the strip).
    """
    states = np.asarray(states)
    n = (states.shape[0] // window) * window
    sp = np.asarray(reduced_section(circle, states[:n]))
    half = float(wall_length(circle)) / 2.0
    s = np.remainder(sp[:, 0], half)
    near = np.abs(s - centre_line_s(circle)) < s_tol
    p = np.where(near, sp[:, 1], -np.inf).reshape(-1, window).max(axis=1)
    p[~np.isfinite(p)] = np.nan
    L = np.asarray(angular_momentum(circle, states[:n])).reshape(-1, window).mean(axis=1)
    return p, L


# --------------------------------------------------------------------------- stored data and the figure


def load_data(path=None) -> dict:
    """The stored maps and runs (``notebooks/data/make_arnold_web_data.py``) as a dict of numpy arrays.

    ``meta`` holds the run's parameters, sizes and timings (parsed from ``meta_json``).

    Raises:
        FileNotFoundError: no stored data at ``path`` (default ``DATA_PATH``).
    """
    import json

    path = pathlib.Path(path) if path is not None else DATA_PATH
    with np.load(path, allow_pickle=False) as f:
        data = {k: f[k] for k in f.files}
    data["meta"] = json.loads(str(data.pop("meta_json")))
    return data


def trusted_frequencies(data: dict, max_spread: float = 1e-8):
    """``(nu1, nu2)`` of the stored grid with NaN where the orbit is not on a torus (``spread > max_spread``)."""
    good = data["spread"] < max_spread
    return np.where(good, data["nu1"], np.nan), np.where(good, data["nu2"], np.nan)


def predicted_lines(data: dict, max_order: int = 9, k2_values=(2,), max_spread: float = 1e-8):
    """The first-order resonances (``resonances``) that cross the stored grid's torus frequencies."""
    nu1, nu2 = trusted_frequencies(data, max_spread)
    box = dict(nu1_range=(np.nanmin(nu1), np.nanmax(nu1)), nu2_range=(np.nanmin(nu2), np.nanmax(nu2)))
    out = []
    for k in resonances(max_order, k2_values, **box):
        if any(len(c) for c in resonance_crossings(k, data["L"], nu1, nu2, axis=0)):
            out.append(k)
    return out


def draw_web(ax, data: dict, eps: float, lines=(), colorbar: bool = True, title: str | None = None):
    """One stored FLI map (``fli_<eps>``) with resonance lines drawn over it.

    Args:
        ax: a matplotlib ``Axes``.
        data: ``load_data()``.
        eps: which map (one of ``data["meta"]`` maps: 0, 1e-4, 1e-3, 1e-2).
        lines: resonances ``(k1, k2, k3)`` to draw (``predicted_lines``); white,
            labelled in the legend.
        colorbar, title: as ``jaxbill.plotting.plot_fli_map``.

    Returns:
        ``ax``.
    """
    from jaxbill.plotting import plot_fli_map

    p, L = data["p"], data["L"]
    dp, dl = (p[1] - p[0]) / 2, (L[1] - L[0]) / 2
    fli = np.asarray(data[f"fli_{eps:g}"], dtype=np.float64)
    lo, hi = np.nanpercentile(fli, [1, 85])
    plot_fli_map(
        ax,
        fli,
        extent=(p[0] - dp, p[-1] + dp, L[0] - dl, L[-1] + dl),
        xlabel="p on the line s = Lw/4  (units of sqrt(2ME))",
        ylabel="L",
        vmin=lo,
        vmax=hi,
        colorbar=colorbar,
        title=title if title is not None else f"eps = {eps:g}",
    )
    nu1, nu2 = trusted_frequencies(data)
    styles = ["-", "--", ":", "-."]
    for i, k in enumerate(lines):
        cs = ax.contour(
            p, L, resonance_value(k, nu1, nu2), [0.0], colors="w", linewidths=0.8, linestyles=styles[i % len(styles)]
        )
        ax.plot([], [], color="w", ls=styles[i % len(styles)], label=f"{k[0]} nu1 + {k[1]} nu2 = {k[2]}")
        del cs
    if len(lines):
        leg = ax.legend(loc="lower right", fontsize=7, facecolor="0.3", labelcolor="w", framealpha=0.7)
        leg.set_zorder(5)
    return ax


def arnold_web_figure(out_dir, quick: bool = True, data_path=None) -> pathlib.Path:
    """Draw the stored FLI maps of the eccentric-ellipse family with the predicted resonance lines.

    Reads ``notebooks/data/arnold_web.npz`` (``load_data``); computes nothing
    long. ``quick=True``: the circle (``eps = 0``) and ``eps = 1e-3``;
    ``quick=False``: all four stored maps and the resonance half-width against
    ``eps`` from the stored scans.

    Args:
        out_dir: folder to write ``arnold_web.png`` into (created if missing).
        quick: two panels instead of five.
        data_path: the stored data (default ``DATA_PATH``).

    Returns:
        the path of the PNG written.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    data = load_data(data_path)
    lines = predicted_lines(data, max_order=9)
    eps_list = (0.0, 1e-3) if quick else (0.0, 1e-4, 1e-3, 1e-2)
    n_ax = len(eps_list) + (0 if quick else 1)
    fig, axes = plt.subplots(1, n_ax, figsize=(5.2 * n_ax, 4.6), squeeze=False)
    for ax, eps in zip(axes[0], eps_list):
        draw_web(ax, data, eps, lines if eps > 0 else (), colorbar=True)
    if not quick:
        ax = axes[0][-1]
        below, above = data["scan_edges"][:, 0], data["scan_edges"][:, 1]
        ax.loglog(data["scan_eps"], (above - below) / 2, "o-", label="half-width of the (0, 2, 0) band")
        e = np.asarray(data["scan_eps"])
        ok = np.isfinite(above - below)
        if ok.sum() >= 2:
            A, g, _, sg = fit_power_law(e[ok], (above - below)[ok] / 2)
            ax.loglog(e, A * e**g, "k:", label=f"fit {A:.3g} eps^{g:.2f}+-{sg:.2f}")
        ax.set_xlabel("eps")
        ax.set_ylabel("half-width in L")
        ax.legend(fontsize=8)
    fig.suptitle(
        f"Stick in the ellipse a = R(1+eps), b = R(1-eps): R = {data['meta']['R']}, ell = {data['meta']['ell']}, "
        f"E = {data['meta']['energy']}; FLI after {data['meta']['sizes']['n_map']} collisions"
    )
    fig.tight_layout()
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "arnold_web.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
