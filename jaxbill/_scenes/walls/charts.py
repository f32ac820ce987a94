"""The explorer's charts of the sticks between walls (``StickBetweenWalls2D/3D.section_chart``).

Kept apart from ``jaxbill._scenes.walls.sections`` (the sections themselves) because
drawing the configuration borrows ``jaxbill.plotting``, which builds on the
sections: this module sits above both.
"""

from __future__ import annotations

import dataclasses
import math

import jax.numpy as jnp
import numpy as np

from jaxbill._scenes.protocols import SectionChart, end_points
from jaxbill._scenes.walls.sections import (
    flight_paths,
    floor_section,
    floor_section_bound,
    floor_seed_points,
    floor_state,
    gyration_radius,
    reduced_wall_section,
)

# -- the explorer's charts of the floor sections (StickBetweenWalls2D/3D.section_chart) ----


def _lower_end_contact(theta):
    """Contact code of the end that ``floor_state`` rests on the floor: P2 (-1) for ``cos theta >= 0``."""
    return jnp.where(jnp.cos(jnp.asarray(theta)) >= 0.0, -1, 1).astype(jnp.int32)


def _walls_start(scene, theta, p, invariants):
    states = floor_state(scene, theta, p, invariants["energy"], invariants.get("spin", 0.0))
    theta, p = jnp.broadcast_arrays(jnp.asarray(theta, jnp.float64), jnp.asarray(p, jnp.float64))
    return states, _lower_end_contact(theta)


def _walls_seeds(scene, count, invariants):
    spin = invariants.get("spin", 0.0)
    theta, p = floor_seed_points(scene, count, invariants["energy"], spin)
    return floor_state(scene, theta, p, invariants["energy"], spin), _lower_end_contact(theta)


def _walls_edge(scene, theta, invariants):
    bound = np.asarray(floor_section_bound(scene, theta, invariants["energy"], invariants.get("spin", 0.0)))
    return np.stack([-bound, bound], axis=-1)


def draw_wall_billiard(
    ax,
    scene,
    theta_range=(0.0, np.pi),
    *,
    color="k",
    shade: bool = True,
):
    """The paper's billiard: floor ``kappa b(theta) = ell|cos theta|`` and ceiling ``h - ell|cos theta|``.

    Drawn in lengths against ``kappa theta`` (aspect equal, so reflections look
    specular); where the two walls cross (``2 ell |cos theta| > h``: the
    stick does not fit) the strip is shaded.
    """
    h, ell = float(scene.h), float(scene.ell)
    kappa = float(np.sqrt(float(scene.inertia) / float(scene.mass)))
    theta = np.linspace(theta_range[0], theta_range[1], 1200)
    floor = ell * np.abs(np.cos(theta))
    ceiling = h - floor
    ax.plot(kappa * theta, floor, color=color, lw=1.2)
    ax.plot(kappa * theta, ceiling, color=color, lw=1.2)
    if shade:
        ax.fill_between(kappa * theta, floor, -0.05 * h, color="0.85", lw=0)
        ax.fill_between(kappa * theta, ceiling, 1.05 * h, color="0.85", lw=0)
        blocked = floor > ceiling
        if blocked.any():
            ax.fill_between(kappa * theta, -0.05 * h, 1.05 * h, where=blocked, color="0.7", lw=0)
    ax.set_xlim(kappa * theta_range[0], kappa * theta_range[1])
    ax.set_ylim(-0.05 * h, 1.05 * h)
    ax.set_aspect("equal")
    ax.set_xlabel(r"$\kappa\,\theta$ (length; $\kappa = \sqrt{I/M}$)")
    ax.set_ylabel("z (length)")
    return ax


def _draw_walls_configuration(ax, scene, state0, orb, color):
    """The reduced billiard ``(kappa theta, z)`` with the stick drawn at its contacts, centred at ``(kappa theta, z)``.

    ``theta`` (the 2D angle, or the 3D polar angle) is taken mod ``pi``, the
    period of the walls, so the whole orbit stays in one cell.
    """
    kappa = float(gyration_radius(scene))
    ell = float(scene.ell)
    draw_wall_billiard(ax, scene, (0.0, np.pi))
    paths = flight_paths(scene, state0, orb, 24).reshape(-1, 2)
    across = np.remainder(paths[:, 0], kappa * np.pi)
    jumps = np.abs(np.diff(across)) > 0.5 * kappa * np.pi
    across = np.insert(across, np.flatnonzero(jumps) + 1, np.nan)
    height = np.insert(paths[:, 1], np.flatnonzero(jumps) + 1, np.nan)
    ax.plot(across, height, color=color, lw=0.8, alpha=0.9)
    ends = np.asarray(end_points(scene, orb.state))  # (n, 2, D), height last
    heights = 0.5 * (ends[:, 0, -1] + ends[:, 1, -1])
    lean = 0.5 * (ends[:, 0] - ends[:, 1])  # (n, D): ell u, from the centre to P1
    # in 3D the polar angle (>= 0); in 2D the signed angle, which the mod pi below keeps apart
    sideways = np.hypot(lean[:, 0], lean[:, 1]) if ends.shape[-1] == 3 else lean[:, 0]
    upward = lean[:, -1]
    theta = np.remainder(np.arctan2(sideways, upward), np.pi)
    centres = np.stack([kappa * theta, heights], axis=-1)
    arm = np.stack([np.sin(theta), np.cos(theta)], axis=-1) * ell
    for centre, reach in zip(centres, arm):
        stick = np.stack([centre - reach, centre + reach])
        ax.plot(stick[:, 0], stick[:, 1], color="0.3", lw=0.9, alpha=0.55)
    ax.set_xlabel(r"$\kappa\,(\theta$ mod $\pi)$ (length); the stick drawn there at each contact")


WALLS_2D_CHART = SectionChart(
    title="floor section",
    axis_labels=(
        r"$\theta$ mod $\pi$ (rad; stick flat at $\pi/2$)",
        r"$p = (I\dot\theta + M v_z\, dz/d\theta)/\sqrt{2 I E'}$",
    ),
    invariant_symbols={"energy": "E'"},
    default_invariants=lambda scene: {"energy": 0.5},
    x_range=lambda scene: (0.0, math.pi),
    edge=_walls_edge,
    start=_walls_start,
    seeds=_walls_seeds,
    points=floor_section,
    draw_configuration=_draw_walls_configuration,
)


def _default_spin(scene) -> float:
    """``I w_z = 0.6 sqrt(2 I E')`` at ``E' = 1/2``: islands and chaos mixed (docs/accuracy.md, walls)."""
    return 0.6 * math.sqrt(float(scene.inertia))


WALLS_3D_CHART = dataclasses.replace(
    WALLS_2D_CHART,
    title="reduced floor section",
    axis_labels=(r"polar angle $\theta$ of the stick (rad)", WALLS_2D_CHART.axis_labels[1]),
    invariant_symbols={"energy": "E'", "spin": r"I w_z"},
    default_invariants=lambda scene: {"energy": 0.5, "spin": _default_spin(scene)},
    points=reduced_wall_section,
)
