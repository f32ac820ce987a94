"""The stick in an ellipse: one trajectory, the point's Birkhoff section and the stick's, and their records."""

from __future__ import annotations

import time

import jax
import numpy as np
from matplotlib.figure import Figure

from jaxbill import plotting
from jaxbill._engine.collision import orbit as run_orbit
from jaxbill._figures.common import ENERGY, Settings, figure_record
from jaxbill._scenes.ellipse.scene import StickInEllipse
from jaxbill._scenes.ellipse.sections import draw_ellipse_orbit, ellipse_length

# Recorded under summary["ellipse"].
ELLIPSE_FILES = ("ellipse.png",)
ELLIPSE_AXES = (2.0, 1.3)
ELLIPSE_ELL = 0.6
ELLIPSE_STATE = (0.1, 0.2, 0.3, 0.7, -0.4, 0.9)


def make_ellipse_figures(settings: Settings, save, bar) -> list:
    """``ellipse.png``: a stick's trajectory, the point's Birkhoff section and the stick's; records for
    ``summary["ellipse"]`` (every section orbit starts on its section, ``E = 1/2``, P1 on the wall)."""
    t0 = time.perf_counter()
    a, b = ELLIPSE_AXES
    stick = StickInEllipse(a=a, b=b, ell=ELLIPSE_ELL)
    point = StickInEllipse(a=a, b=b, ell=0.0)
    state0 = np.asarray(ELLIPSE_STATE)
    trajectory = run_orbit(stick, state0, settings.ellipse_trajectory_collisions)
    count, n = settings.ellipse_orbits, settings.ellipse_collisions
    # Seeds along the middle of the section's s axis, p from -0.95 to 0.95.
    length = float(ellipse_length(point))
    seeds_p = np.linspace(-0.95, 0.95, count)
    seeds = np.stack([np.full(count, 0.3 * length), seeds_p], axis=-1)
    records, panels = [], []
    for label, scene in (("point (ell = 0)", point), (f"stick (ell = {ELLIPSE_ELL:g}, I = M ell^2)", stick)):
        states0 = np.asarray(scene.section_state(seeds, energy=ENERGY))
        orb = run_orbit(scene, states0, n)
        points = np.asarray(scene.section(orb.state, orb.contact))
        energies = np.asarray(scene.energy(orb.state))
        e0 = np.asarray(scene.energy(states0))[:, None]
        records.append(
            {
                "label": label,
                "scene": {
                    "a": a,
                    "b": b,
                    "ell": float(scene.ell),
                    "kind": scene.kind,
                    "inertia": float(scene.inertia),
                    "mass": float(scene.mass),
                },
                "orbits": count,
                "collisions_per_orbit": n,
                "collisions": count * n,
                "energy_drift": float(np.max(np.abs(energies / e0 - 1.0))),
                "energy": ENERGY,
            }
        )
        panels.append((label, points))
    fig = Figure(figsize=(15, 4.8), layout="constrained")
    ax_orbit, *ax_sections = fig.subplots(1, 3)
    one = jax.device_get(trajectory)  # an Orbit of numpy arrays
    draw_ellipse_orbit(ax_orbit, stick, state0, one, "tab:blue")
    ax_orbit.set_title(
        f"stick, a = {a:g}, b = {b:g}, ell = {ELLIPSE_ELL:g}: {settings.ellipse_trajectory_collisions} collisions"
    )
    colors = plotting.orbit_colors(count)
    for ax, (_label, points) in zip(ax_sections, panels):
        for k in range(count):
            ax.plot(points[k, :, 0], points[k, :, 1], ".", color=colors[k], ms=1.0)
        ax.set_xlim(0.0, length)
        ax.set_ylim(-1.02, 1.02)
        ax.set_xlabel("s: arc length of the contact from (a, 0) (length)")
        ax.set_ylabel(r"$p = \sqrt{M}\,v_t/\sqrt{2E}$")
    ax_sections[0].set_title("point: Birkhoff section (area-preserving; integrable)")
    ax_sections[1].set_title("stick: the touching end's (s, p), a projection")
    fig.suptitle(f"Stick in an ellipse: {count} orbits x {n} collisions per section, E = 1/2")
    path = save(fig, ELLIPSE_FILES[0])
    bar.advance("ellipse")
    description = "stick in an ellipse: one trajectory, the point's Birkhoff section, the stick's"
    return [figure_record("ellipse", path, description, records, t0)]
