"""What every periodic-orbit solver shares: the result, the stability labels and the differentiable solve.

Stability labels
----------------
Labels, from the trace ``tr = mu + 1/mu`` of the nontrivial multipliers
``mu, 1/mu``: elliptic (``|tr| < 2``: linearly stable), parabolic (``|tr| = 2``
to ``parabolic_tol``), hyperbolic (``tr > 2``) and inverse hyperbolic
(``tr < -2``: hyperbolic with reflection).

Derivatives
-----------
The solve is made differentiable with respect to the scene's leaves (and the
target energy and angular momentum) by the implicit function theorem: the
solution ``zeta*`` is refined by one Gauss-Newton step
``zeta* - J^+ F(zeta*; scene)`` with the Jacobian ``J`` held constant, whose
derivative is ``-J^+ dF/dscene``, never a derivative of the iterations.
"""

from __future__ import annotations

from typing import Protocol, cast

import equinox as eqx
import jax
import jax.numpy as jnp
import optimistix as optx
from jaxtyping import Array, Bool, Complex, Float, Int

from jaxbill._scenes.protocols import PERIODIC_SYMMETRIES, HasAngularMomentum, Scene, has_angular_momentum

ELLIPTIC, PARABOLIC, HYPERBOLIC, INVERSE_HYPERBOLIC = 0, 1, 2, 3
STABILITY_LABELS = ("elliptic", "parabolic", "hyperbolic", "inverse hyperbolic")

# A solution with a flight shorter than this (in units of the table's length / speed) slides
# along the wall (a grazing limit) and is not reported as converged.
MIN_FLIGHT = 1e-6


class PeriodicOrbit(eqx.Module):
    """A (relative) periodic orbit of the collision map.

    For a batch every field has a leading batch axis.

    Attributes (``S = scene.state_size``):
        state: ``(S,)`` the state just after the orbit's first collision.
        states: ``(p, S)`` the states just after each of its ``p`` collisions;
            ``states[-1]`` is ``state`` rotated by ``rotation`` about the origin
            (with the ends possibly exchanged, ``alpha -> alpha + pi``).
            Between walls: shifted horizontally by ``(vx, vy) * period`` and,
            in 3D, with ``u`` and ``w`` turned by ``rotation`` about the vertical.
        contacts: ``(p,)`` contact codes of those collisions.
        points: ``(p, K)`` the reduced section coordinates of the ``p`` section
            points (``points[0]`` is the fixed point solved for; the coordinates
            are described in ``jaxbill._analysis.periodic_rotation``). Between walls: ``(theta, z, vz,
            omega)`` in 2D, ``(u_z, z, vz, (w x u)_z, w_z)`` in 3D.
        period: ``()`` the orbit's period in time (sum of the ``p`` flight times).
        rotation: ``()`` the rotation ``theta`` in ``[-pi, pi)`` after ``p``
            collisions (0 for a periodic orbit proper; always 0 in 2D).
        residual: ``()`` max-norm of the scaled residual (0 to rounding at a solution).
        multipliers: ``(2,)`` complex, the nontrivial monodromy multipliers
            ``mu, 1/mu`` (trivial ones removed: see
            ``jaxbill._analysis.periodic_rotation``).
        trace: ``()`` ``mu + 1/mu``.
        stability: ``()`` int, index into ``STABILITY_LABELS``.
        converged: ``()`` bool: ``residual <= tol`` and no flight shorter than
            ``1e-6 R / speed`` (sliding along the wall, the grazing limit,
            solves the equations trivially and is rejected); between walls
            also ``1e-6 h / speed``, and every contact a single one.
        energy, angular_momentum: ``()`` of the orbit (``angular_momentum``
            is NaN for ``StickBetweenWalls2D``, which conserves none).
        monodromy: ``(K', K')`` the Jacobian of the reduced ``p``-map at the
            fixed point, trivial directions included (the stick in a circle: in
            the reduced coordinates; between walls: in the section coordinates
            of ``jaxbill._scenes.walls.periodic``).
        p: number of collisions in one period (static).
    """

    state: Float[Array, "*B S"]
    states: Float[Array, "*B p S"]
    contacts: Int[Array, "*B p"]
    points: Float[Array, "*B p K"]
    period: Float[Array, "*B"]
    rotation: Float[Array, "*B"]
    residual: Float[Array, "*B"]
    multipliers: Complex[Array, "*B M"]
    trace: Float[Array, "*B"]
    stability: Int[Array, "*B"]
    converged: Bool[Array, "*B"]
    energy: Float[Array, "*B"]
    angular_momentum: Float[Array, "*B"]
    monodromy: Float[Array, "*B k k"]
    p: int = eqx.field(static=True)

    @property
    def label(self) -> str:
        """The stability label (``"elliptic"``, ...) of an unbatched orbit."""
        return STABILITY_LABELS[int(self.stability)]


def stability_index(trace, parabolic_tol):
    """Index into ``STABILITY_LABELS`` from the trace ``mu + 1/mu``."""
    stability = jnp.where(
        jnp.abs(jnp.abs(trace) - 2.0) <= parabolic_tol,
        PARABOLIC,
        jnp.where(jnp.abs(trace) < 2.0, ELLIPTIC, jnp.where(trace > 0, HYPERBOLIC, INVERSE_HYPERBOLIC)),
    )
    return stability.astype(jnp.int32)


class LeastSquaresProblem(Protocol):
    """The residual ``F(zeta)`` of a solver's equations in its scaled unknowns ``zeta``."""

    def __call__(self, zeta: jax.Array, args: object = None, /) -> jax.Array: ...


def solve_least_squares(problem: LeastSquaresProblem, zeta0, max_steps):
    """Levenberg-Marquardt with the problem's parameters held constant, differentiable by the IFT.

    Returns the solution (differentiable in the problem's parameters by the
    implicit function theorem) and the residual's Jacobian there.
    """
    frozen = jax.lax.stop_gradient(problem)
    solver = optx.LevenbergMarquardt(rtol=1e-14, atol=1e-14)
    sol = optx.least_squares(frozen, solver, zeta0, max_steps=max_steps, throw=False)
    zeta = jax.lax.stop_gradient(sol.value)
    jac = jax.lax.stop_gradient(jax.jacfwd(frozen)(zeta))
    # Implicit function theorem: a Gauss-Newton step zeta - J^+ F(zeta; parameters)
    # with J held constant has the derivative -J^+ dF/dparameters. Its value is
    # left out (F = 0 at a solution; where the solve failed, the step could only
    # make things worse).
    r = problem(zeta)
    step = jnp.linalg.pinv(jac) @ (r - jax.lax.stop_gradient(r))
    return zeta - step, jac


def angular_momentum_or_nan(scene: Scene, state: jax.Array) -> jax.Array:
    """The scene's angular momentum of ``state``, NaN for a scene without one (the 2D walls)."""
    if not has_angular_momentum(scene):
        return jnp.full((), jnp.nan)
    return cast(HasAngularMomentum, scene).angular_momentum(state)


def periodic_symmetry_of(scene) -> str:
    """The symmetry ``scene`` says its periodic orbits divide out (``HasPeriodicSymmetry``)."""
    symmetry = getattr(scene, "periodic_symmetry", None)
    if symmetry not in PERIODIC_SYMMETRIES:
        raise TypeError(
            f"scene: {type(scene).__name__} has no periodic_symmetry (one of {PERIODIC_SYMMETRIES}; "
            "the HasPeriodicSymmetry protocol of jaxbill._scenes.protocols): find_periodic_orbit cannot search it"
        )
    return symmetry
