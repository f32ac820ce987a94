r"""The periodic Lorentz gas: a point among discs on a square or a triangular lattice, one cell at a time.

The discs of radius ``r`` sit at the points of a lattice with distance
``spacing`` between nearest centres: the square lattice, or the triangular one
(the "hexagonal" Lorentz gas, whose cell is a regular hexagon). The table is
one cell, the lattice's Wigner-Seitz cell about a disc (the points nearer that
disc's centre than any other), whose sides are **periodic walls**
(``PeriodicWall``): a point that reaches one goes on into the neighbouring
cell, with no impulse.

How the orbit stays exact (the representation). The state keeps the
**unfolded** position: ``(x, y)`` is where the point is in the plane, never
wrapped. Each flight runs in one cell, the one its start lies in
(``cell_origin``), and the walls see the position relative to that cell's
centre. A crossing of a periodic wall is a collision that changes nothing: the
state after it is the state before it, moved to the wall; the next flight
starts on the boundary, and its cell is the one the velocity points into. So

* the orbit is the same straight flights and the same bounces as in the
  plane, computed from the one position, with no translation added or rounded
  (the displacement ``x(t) - x(0)`` and with it the mean-square displacement
  are read off the states);
* a crossing's tangent map is the identity (the flight to the wall and the
  flight after it compose into the flight across it);
* ``Orbit.contact`` names the wall crossed (``3 + i``): the crossings of each
  side are counted by ``jb.run``'s tallies, and ``cell_index`` gives the
  lattice coordinates of the cell a state's flight runs in.

The cell of a flight (``cell_origin``). The nearest lattice point to the start
(among the four corners of its lattice parallelogram), then, twice, a step
across the wall the start lies on (within ``WALL_TOLERANCE`` of the spacing,
plus a few ulps of the position) and moves out through, the fastest-leaving
first: one step leaves a side, two leave a corner (three cells meet at a
corner of a hexagon, four at a square's; which of them the velocity points
into is decided one wall at a time). The cell found has no wall that the start
is on and leaves through, so its first crossing is at a positive time, and
at least the tolerance away: the orbit never stalls at a boundary. The same
expressions give the rooms of the walls as ``HalfPlane.exit_time``.

Only a point particle moves in it (the discs disperse). Gaps are lengths (about
the distance to a wall or a disc near it), in units of ``spacing``.
"""

from __future__ import annotations

import math
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbill._engine.validation import WALL_TOLERANCE, check_parameter, is_concrete, real_parameter
from jaxbill._scenes.tables.base import Table
from jaxbill._scenes.tables.flat import HalfPlane
from jaxbill._scenes.tables.obstacles import DiscObstacle

LATTICES = ("square", "hexagonal")
_HEIGHT = math.sqrt(3.0) / 2.0  # the triangular lattice's second vector is spacing (1/2, sqrt(3)/2)
# Ulps of the position's size a start may be off a wall by rounding (the unfolded position grows).
_POSITION_ULPS = 16.0


class PeriodicWall(HalfPlane):
    """A side of a periodic cell, ``n . P <= d``: a point that reaches it goes on into the neighbouring cell.

    A ``HalfPlane`` (its gap, normal and exit time) with ``periodic = True``:
    the scene applies no impulse at it, and it is no part of the boundary a
    section runs along (its ``length`` is 0).
    """

    periodic: ClassVar[bool] = True


def _directions(lattice: str) -> tuple:
    """The unit vectors from a lattice point to its nearest neighbours, anticlockwise from +x."""
    count = 4 if lattice == "square" else 6
    return tuple((math.cos(2.0 * math.pi * k / count), math.sin(2.0 * math.pi * k / count)) for k in range(count))


class LorentzGas(Table):
    """The periodic Lorentz gas: discs of ``radius`` on a square or triangular lattice of ``spacing``.

    Args:
        radius: the discs' radius, ``0 < radius <= spacing/2`` (length: the discs do not overlap; at
            ``spacing/2`` they touch, and a point is shut in the space between three or four of them).
        spacing: the distance between nearest disc centres, ``> 0`` (length).
        lattice: ``"square"`` (cells are squares of side ``spacing``) or
            ``"hexagonal"`` (the triangular lattice; cells are regular hexagons
            with vertical sides, ``spacing`` apart).

    The walls, in the order of the contact codes (``3 + i``): the disc at the
    cell's centre, then the cell's sides (``PeriodicWall``), anticlockwise from
    the one facing ``+x``. A state's ``(x, y)`` is the unfolded position
    (module docstring): a start may lie in any cell. Only ``jb.PointBody``
    moves in it. The hexagonal gas has a finite horizon (no flight is longer
    than a few spacings) for ``spacing < 4 radius / sqrt(3)`` (``finite_horizon``);
    the square one never has.
    """

    spacing: jax.Array  # first: the unit of length (the explorer keeps it fixed)
    radius: jax.Array
    lattice: str = eqx.field(static=True)

    name: ClassVar[str] = "the Lorentz gas"
    # The unfolded position runs over the whole plane: no centre to take an angular momentum about.
    has_centre: ClassVar[bool] = False

    def __init__(self, radius, spacing, lattice: str = "hexagonal"):
        if lattice not in LATTICES:
            raise ValueError(f"lattice must be one of {LATTICES}; got {lattice!r}")
        self.radius, self.spacing = (jnp.asarray(v, dtype=jnp.float64) for v in (radius, spacing))
        self.lattice = lattice
        if is_concrete(self.radius) and is_concrete(self.spacing):
            self.check()

    def check(self) -> None:
        d = real_parameter("spacing", self.spacing)
        check_parameter("spacing", d, np.isfinite(d) & (d > 0), "> 0 and finite (the distance between centres)")
        r = real_parameter("radius", self.radius)
        within = f"> 0 and <= spacing/2 = {d / 2} (the discs do not overlap)"
        check_parameter("radius", r, (r > 0) & (r <= d / 2), within)

    def parameters_are_valid(self):
        d, r = self.spacing, self.radius
        return (d > 0) & jnp.isfinite(d) & (r > 0) & (r <= 0.5 * d)

    @property
    def _neighbours(self) -> tuple:
        """The lattice vectors to the nearest neighbours ``(bx, by)`` (lengths), one per wall."""
        return tuple((self.spacing * ux, self.spacing * uy) for ux, uy in _directions(self.lattice))

    @property
    def pieces(self):
        half = 0.5 * self.spacing
        zero = 0.0 * self.radius  # from a parameter: a Pallas kernel lowers no operation on a constant
        walls = tuple(
            PeriodicWall(ux, uy, half, 0.0, 0.0, 1.0, self.spacing, 0.0) for ux, uy in _directions(self.lattice)
        )
        return (DiscObstacle((zero, zero), self.radius), *walls)

    @property
    def piece_names(self):
        count = len(_directions(self.lattice))
        return ("the disc", *(f"the side towards {round(360 * k / count)} degrees" for k in range(count)))

    # -- the cell of a flight (module docstring) -------------------------------------------------

    def _nearest_lattice_point(self, x, y) -> tuple:
        d = self.spacing
        if self.lattice == "square":
            return jnp.floor(x / d + 0.5) * d, jnp.floor(y / d + 0.5) * d
        j0 = jnp.floor(y / (_HEIGHT * d))
        i0 = jnp.floor(x / d - 0.5 * (y / (_HEIGHT * d)))
        # The nearest lattice point is a corner of the lattice parallelogram the point is in.
        best_x, best_y = (i0 + 0.5 * j0) * d, (_HEIGHT * j0) * d
        best = (x - best_x) ** 2 + (y - best_y) ** 2
        for di, dj in ((1.0, 0.0), (0.0, 1.0), (1.0, 1.0)):
            i, j = i0 + di, j0 + dj
            px, py = (i + 0.5 * j) * d, (_HEIGHT * j) * d
            distance = (x - px) ** 2 + (y - py) ** 2
            nearer = distance < best
            best_x, best_y = jnp.where(nearer, px, best_x), jnp.where(nearer, py, best_y)
            best = jnp.where(nearer, distance, best)
        return best_x, best_y

    def cell_origin(self, x, y, vx, vy):
        """The centre of the cell a flight from ``(x, y)`` at ``(vx, vy)`` runs in (module docstring)."""
        ox, oy = self._nearest_lattice_point(x, y)
        position_ulps = _POSITION_ULPS * np.finfo(np.float64).eps * (jnp.abs(x) + jnp.abs(y))
        tolerance = WALL_TOLERANCE * self.spacing + position_ulps
        walls = self.pieces[1:]
        for _ in range(2):
            lx, ly = x - ox, y - oy
            fastest = jnp.zeros_like(x)
            step_x, step_y = jnp.zeros_like(x), jnp.zeros_like(x)
            for wall, (bx, by) in zip(walls, self._neighbours):
                room = wall.d - (wall.nx * lx + wall.ny * ly)
                closing = wall.nx * vx + wall.ny * vy
                leaving = (room <= tolerance) & (closing > fastest)
                fastest = jnp.where(leaving, closing, fastest)
                step_x, step_y = jnp.where(leaving, bx, step_x), jnp.where(leaving, by, step_y)
            ox, oy = ox + step_x, oy + step_y
        return ox, oy

    def cell_index(self, states) -> jax.Array:
        """The lattice coordinates ``(..., 2)`` (int) of the cell each state's flight runs in: ``(i, j)`` with
        the cell's centre at ``i a1 + j a2`` (``a1 = spacing (1, 0)``; ``a2 = spacing (0, 1)`` on the square
        lattice, ``spacing (1/2, sqrt(3)/2)`` on the triangular one)."""
        states = jnp.asarray(states, dtype=jnp.float64)
        ox, oy = self.cell_origin(states[..., 0], states[..., 1], states[..., 3], states[..., 4])
        d = self.spacing
        if self.lattice == "square":
            i, j = ox / d, oy / d
        else:
            j = oy / (_HEIGHT * d)
            i = ox / d - 0.5 * j
        return jnp.stack([jnp.round(i), jnp.round(j)], axis=-1).astype(jnp.int64)

    def cells_covering(self, x_low: float, x_high: float, y_low: float, y_high: float) -> list:
        """The centres of the cells that meet the box (floats; a picture draws the disc of each)."""
        d = float(self.spacing)
        a1 = np.array([d, 0.0])
        a2 = np.array([0.0, d]) if self.lattice == "square" else np.array([0.5 * d, _HEIGHT * d])
        corners = np.array([[x_low, y_low], [x_low, y_high], [x_high, y_low], [x_high, y_high]])
        lattice = np.linalg.solve(np.stack([a1, a2], axis=1), corners.T)
        low, high = np.floor(lattice.min(axis=1)) - 1, np.ceil(lattice.max(axis=1)) + 1
        centres = []
        for i in np.arange(low[0], high[0] + 1):
            for j in np.arange(low[1], high[1] + 1):
                x, y = i * a1 + j * a2
                if x_low - d <= x <= x_high + d and y_low - d <= y <= y_high + d:
                    centres.append((float(x), float(y)))
        return centres

    # -- geometry --------------------------------------------------------------------------------

    @property
    def cell_area(self) -> jax.Array:
        """The cell's area, ``spacing^2`` or ``(sqrt(3)/2) spacing^2`` (area)."""
        return (1.0 if self.lattice == "square" else _HEIGHT) * self.spacing**2

    @property
    def area(self) -> jax.Array:
        """The area of a cell outside its disc (area)."""
        return self.cell_area - jnp.pi * self.radius**2

    @property
    def mean_free_path(self) -> jax.Array:
        """Santalo's ``pi A / P`` with ``A`` the cell's area outside the disc and ``P = 2 pi r``: the mean flight
        between bounces off discs (crossings of the cell's sides are not bounces) (length)."""
        return self.area / (2.0 * self.radius)

    @property
    def finite_horizon(self) -> bool:
        """Whether every flight ends within a bounded length (concrete parameters): the triangular lattice with
        ``spacing < 4 radius / sqrt(3)``; never the square lattice."""
        if self.lattice == "square":
            return False
        return bool(np.all(np.asarray(self.spacing) < 4.0 * np.asarray(self.radius) / math.sqrt(3.0)))

    @property
    def size(self):
        return self.spacing

    @property
    def extent(self):
        half = 0.5 * self.spacing
        tall = half if self.lattice == "square" else self.spacing / math.sqrt(3.0)
        return -half, half, -tall, tall
