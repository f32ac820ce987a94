"""A user's table: the region ``F(x, y) <= 0`` of a smooth convex function, its derivatives by autodiff.

The gap is ``-F`` (in ``F``'s own units). Its gradient and Hessian come from
JAX's autodiff; the search needs bounds over the table on ``|grad F|`` (``G``)
and on the largest eigenvalue of ``Hess F`` (``H``; ``F`` is convex, so the
smallest is ``>= 0``): the flight bounds then follow as for any piece
(``jaxbill._scenes.tables.base.generic_curvature_bounds``):
``-(H |P'|^2 + G omega^2 rho) <= g'' <= G omega^2 rho``.

Given or estimated. The user may give ``G`` and ``H``. Otherwise they are
estimated on a grid of ``ESTIMATE_GRID^2`` points over ``extent`` (those with
``F <= 0``, the table, and a band of a tenth of the box around it), and
multiplied by ``ESTIMATE_MARGIN``: a smooth function's maxima between grid
points exceed the grid's by a relative amount of order ``(spacing / scale)^2``,
far below the margin for a table resolved by the grid. The same grid checks
convexity: a negative eigenvalue of ``Hess F`` below ``-1e-9 H`` anywhere on
it is a ``ValueError``.

During a run the gap's own curvature ``g''`` is compared with the bounds at
every root step: where it falls outside (a bound too small, a function not
convex where the grid did not look), the orbit is poisoned with NaN rather
than continued past a root the search may have stepped over.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbill._engine.validation import check_parameter, real_parameter
from jaxbill._scenes.tables.base import Motion, Piece, Table, generic_curvature_bounds

ESTIMATE_GRID = 201
ESTIMATE_MARGIN = 1.5
# Rounding in the gap's computed curvature, relative to the bound, tolerated by the run-time check.
_CURVATURE_SLACK = 1e-9


class FunctionWall(Piece):
    """The wall ``F = 0`` of a user's convex function, ``g = -F``; ``gradient_bound`` and ``hessian_bound`` bound
    ``|grad F|`` and the largest eigenvalue of ``Hess F`` over the table."""

    function: Callable = eqx.field(static=True)
    gradient_bound: jax.Array
    hessian_bound: jax.Array
    unit: jax.Array

    # The search checks the gap's curvature against the bounds at every step (module docstring).
    checks_curvature: ClassVar[bool] = True

    def gap(self, x, y):
        return -self.function(x, y)

    def gradient(self, x, y):
        gx, gy = jnp.vectorize(jax.grad(self.function, argnums=(0, 1)))(x, y)
        return -gx, -gy

    def hessian_form(self, x, y, dx, dy):
        gradient = jax.grad(self.function, argnums=(0, 1))

        def one(x_, y_, dx_, dy_):
            _, (hx, hy) = jax.jvp(gradient, (x_, y_), (dx_, dy_))
            return -(hx * dx_ + hy * dy_)

        return jnp.vectorize(one)(x, y, dx, dy)

    @property
    def gap_scale(self):
        return self.unit

    def curvature_bounds(self, motion: Motion):
        return generic_curvature_bounds(motion, -self.hessian_bound, 0.0, self.gradient_bound)


class ConvexTable(Table):
    """The table ``F(x, y) <= 0`` of a smooth convex function ``F``.

    Args:
        function: ``F(x, y)``, a jittable function of two scalars (float64) that is
            convex, ``< 0`` inside and ``0`` on the wall, with a nonzero gradient there.
        extent: ``(x_low, x_high, y_low, y_high)``, a box that holds the table.
        gradient_bound: a bound on ``|grad F|`` over the table (``None``: estimated).
        hessian_bound: a bound on the largest eigenvalue of ``Hess F`` over the table
            (``None``: estimated).
        name: how messages name the wall.

    Raises:
        ValueError: for a box that is not a box, a function that is not convex on
            the estimation grid, a table that is empty or not inside the box,
            or bounds that are not positive.
    """

    wall: FunctionWall
    box: tuple
    label: str = eqx.field(static=True)

    section_names: ClassVar[tuple[str, ...]] = ()

    def __init__(self, function, extent, gradient_bound=None, hessian_bound=None, name: str = "the table"):
        if not callable(function):
            raise ValueError(f"function must be a callable F(x, y); got {type(function).__name__}")
        box = real_parameter("extent", extent)
        if box.shape != (4,) or not np.all(np.isfinite(box)) or box[0] >= box[1] or box[2] >= box[3]:
            raise ValueError(f"extent must be (x_low, x_high, y_low, y_high) with low < high, finite; got {extent!r}")
        estimated_g, estimated_h, unit = _estimate(function, box)
        if gradient_bound is None:
            gradient_bound = ESTIMATE_MARGIN * estimated_g
        if hessian_bound is None:
            hessian_bound = ESTIMATE_MARGIN * estimated_h
        for label, value in (("gradient_bound", gradient_bound), ("hessian_bound", hessian_bound)):
            v = real_parameter(label, value)
            check_parameter(label, v, np.isfinite(v) & (v > 0), "> 0 and finite")
        self.wall = FunctionWall(
            function, *(jnp.asarray(v, jnp.float64) for v in (gradient_bound, hessian_bound, unit))
        )
        self.box = tuple(jnp.asarray(v, jnp.float64) for v in box)
        self.label = name

    @property
    def name(self) -> str:  # pyright: ignore[reportIncompatibleVariableOverride]
        return self.label

    @property
    def pieces(self):
        return (self.wall,)

    @property
    def piece_names(self):
        return (self.label,)

    @property
    def size(self):
        return 0.5 * jnp.maximum(self.box[1] - self.box[0], self.box[3] - self.box[2])

    @property
    def extent(self):
        return self.box

    @property
    def diameter(self):
        return jnp.sqrt((self.box[1] - self.box[0]) ** 2 + (self.box[3] - self.box[2]) ** 2)


def _estimate(function, box: np.ndarray) -> tuple[float, float, float]:
    """``(max |grad F|, max eigenvalue of Hess F, gap unit)`` on the grid over the table (module docstring);
    ValueError for an empty table, one that reaches the box's edge, or a function found not convex."""
    x = np.linspace(box[0], box[1], ESTIMATE_GRID)
    y = np.linspace(box[2], box[3], ESTIMATE_GRID)
    gx, gy = (a.ravel() for a in np.meshgrid(x, y, indexing="ij"))
    values = np.asarray(jax.vmap(function)(jnp.asarray(gx), jnp.asarray(gy)), dtype=np.float64)
    if not np.all(np.isfinite(values)):
        raise ValueError("function must be finite over the extent")
    inside = values <= 0.0
    if not np.any(inside):
        raise ValueError("function is > 0 everywhere in extent: the table is empty (or outside the box)")
    on_edge = inside.reshape(ESTIMATE_GRID, ESTIMATE_GRID)
    if on_edge[0].any() or on_edge[-1].any() or on_edge[:, 0].any() or on_edge[:, -1].any():
        raise ValueError("extent must hold the whole table: F <= 0 reaches the edge of the box")
    gradient = jax.vmap(jax.grad(function, argnums=(0, 1)))(jnp.asarray(gx), jnp.asarray(gy))
    hessian = jax.vmap(jax.hessian(lambda p: function(p[0], p[1])))(jnp.stack([gx, gy], axis=-1))
    norms = np.hypot(np.asarray(gradient[0]), np.asarray(gradient[1]))
    smooth = np.isfinite(norms) & np.all(np.isfinite(np.asarray(hessian)), axis=(1, 2))
    if not np.all(smooth):
        # A kink (|P| at the origin) has no Hessian bound for the search to step by.
        worst = int(np.argmin(smooth))
        raise ValueError(
            "function must be twice differentiable over the extent (finite gradient and Hessian by autodiff); "
            f"they are not finite at ({gx[worst]:.6g}, {gy[worst]:.6g})"
        )
    eigen = np.linalg.eigvalsh(np.asarray(hessian))
    # The band around the table where a contact point may stray by rounding, and the table.
    spacing = max(box[1] - box[0], box[3] - box[2]) / (ESTIMATE_GRID - 1)
    near = values <= np.max(norms[inside]) * 10 * spacing
    largest = float(np.max(eigen[near, 1]))
    if float(np.min(eigen[near, 0])) < -1e-9 * max(largest, 1e-300):
        worst = int(np.argmin(np.where(near, eigen[:, 0], np.inf)))
        raise ValueError(
            f"function must be convex: its Hessian has the eigenvalue {float(eigen[worst, 0]):.3g} < 0 at "
            f"({gx[worst]:.6g}, {gy[worst]:.6g})"
        )
    if largest <= 0.0:
        raise ValueError("function must be strictly convex somewhere (a table of straight walls: use jb.Polygon)")
    rim = inside & (values > -np.max(norms) * 2 * spacing)
    boundary_gradient = float(np.median(norms[rim] if np.any(rim) else norms[inside]))
    size = 0.5 * max(box[1] - box[0], box[3] - box[2])
    return float(np.max(norms[near])), largest, boundary_gradient * size
