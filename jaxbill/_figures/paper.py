"""The paper's figures: Figs. 1-3, the ell and inertia scans, Fig. 2's orbits in the reduced section and the
spiral column, and the records of their panels (counts, invariant drifts, chaotic share)."""

from __future__ import annotations

import time

import jax
import numpy as np
from matplotlib.figure import Figure

from jaxbill import plotting
from jaxbill._analysis.section_measures import CHAOTIC_DIVERGENCE, curve_thickness, divergence, twin_states
from jaxbill._engine.collision import orbit as run_orbit
from jaxbill._figures.common import ENERGY, Settings, common_value, figure_record
from jaxbill._scenes.circle.scene import StickInCircle
from jaxbill._scenes.circle.sections import (
    half_corner_angle,
    paper_section,
    reduced_section,
    section_seeds,
    section_state,
)

ANGULAR_MOMENTUM = 0.0
R = 2.0

# Fig. 2's two orbits, as section points (s, p) at ell = 1.9, E = 1/2, L = 0:
# a torus of the big island round the stick bouncing along a diameter
# (s = R beta_max, the middle of the arc of P1), and an orbit in the chaotic
# layer near a lens corner.
FIG2_REGULAR = ("middle", 0.5)
FIG2_CHAOTIC = (0.05, 0.9)
FIG1_STATE = (0.3, -0.2, 0.4, 0.62, 0.55, 0.45)


# -- computing ---------------------------------------------------------------


def _scene_record(scene: StickInCircle) -> dict:
    inertia = float(np.asarray(scene.inertia))
    return {
        "R": float(scene.R),
        "ell": float(scene.ell),
        "mass": float(scene.mass),
        "inertia": "inf" if np.isinf(inertia) else inertia,
        "kind": scene.kind,
    }


def _conserves_angular_momentum(scene: StickInCircle) -> bool:
    # A stick that never turns (the lens) takes the wall's torque and gives nothing back to a spin.
    return scene.body_turns or scene.body_is_point


def invariant_drifts(scene: StickInCircle, states0, orbit) -> tuple[float, float | None]:
    """Worst energy and angular-momentum drift of a batch of orbits (see the package docstring)."""
    states0 = np.asarray(states0, dtype=np.float64)
    states = np.asarray(orbit.state, dtype=np.float64)
    e0 = np.asarray(scene.energy(states0))[..., None]
    e = np.asarray(scene.energy(states))
    energy_drift = float(np.max(np.abs(e / e0 - 1.0)))
    if not _conserves_angular_momentum(scene):
        return energy_drift, None
    l0 = np.asarray(scene.angular_momentum(states0))[..., None]
    l = np.asarray(scene.angular_momentum(states))
    scale = float(scene.R) * np.sqrt(2.0 * float(scene.mass) * e0)
    return energy_drift, float(np.max(np.abs(l - l0) / scale))


def _panel(label, scene, states0, orbit, **extra) -> dict:
    energy_drift, momentum_drift = invariant_drifts(scene, states0, orbit)
    states0 = np.asarray(states0)
    batch = states0.reshape(-1, 6)
    n = int(np.asarray(orbit.t).shape[-1])
    record = {
        "label": label,
        "scene": _scene_record(scene),
        "energy": common_value(scene.energy(batch)),
        "angular_momentum": (
            common_value(scene.angular_momentum(batch)) if _conserves_angular_momentum(scene) else None
        ),
        "orbits": len(batch),
        "collisions_per_orbit": n,
        "collisions": len(batch) * n,
        "missed_or_failed": int(np.sum(np.asarray(orbit.contact) == 0)),
        "energy_drift": energy_drift,
        "angular_momentum_drift": momentum_drift,
    }
    record.update(extra)
    # Orbits run beside their twins (one batch: the originals, then the twins) say so: a rerun of
    # the same batch reproduces them bit for bit.
    record["twins"] = "divergence" in extra or "chaotic_fraction" in extra or "twin_divergence" in extra
    record["states0"] = batch.tolist()
    return record


def _with_twins(scene, states0, n):
    """Run orbits and their twins in one batch; return (orbit of the originals, divergence per orbit)."""
    states0 = np.asarray(states0)
    both = run_orbit(scene, np.concatenate([states0, twin_states(states0)]), n)
    count = len(states0)
    orb = jax.tree.map(lambda leaf: leaf[:count], both)
    return orb, divergence(scene, both.state[:count], both.state[count:], states0)


def _thicknesses(points) -> list[float]:
    return [curve_thickness(p) for p in np.asarray(points)]


def _section_panel(scene, settings: Settings, label: str):
    """Seeds, orbits and both sections of one scan panel at (E, L) = (1/2, 0)."""
    states0 = section_seeds(scene, settings.section_orbits, ENERGY, ANGULAR_MOMENTUM)
    orb, spread = _with_twins(scene, states0, settings.section_collisions)
    reduced = np.asarray(reduced_section(scene, orb.state))
    projected = np.asarray(paper_section(scene, orb.state))
    chaotic = spread > CHAOTIC_DIVERGENCE
    record = _panel(label, scene, states0, orb, chaotic_fraction=float(np.mean(chaotic)))
    return record, reduced, projected, chaotic


def _fig2_states(scene):
    middle = float(scene.R) * float(half_corner_angle(scene))
    s = np.array([middle if FIG2_REGULAR[0] == "middle" else FIG2_REGULAR[0], FIG2_CHAOTIC[0]])
    p = np.array([FIG2_REGULAR[1], FIG2_CHAOTIC[1]])
    return section_state(scene, s, p, ENERGY, ANGULAR_MOMENTUM)


# -- drawing -----------------------------------------------------------------


def _draw_regular_over_chaotic(ax, points, chaotic, kind, title=None):
    """Chaotic orbits in light grey (every third point), regular ones on top, one colour per orbit."""
    if chaotic.any():
        plotting.draw_section(ax, points[chaotic][:, ::3], kind, colors="0.78", markersize=0.8)
    if (~chaotic).any():
        plotting.draw_section(ax, points[~chaotic], kind, markersize=0.8)
    if title is not None:
        ax.set_title(title)


def _scan_figure(panels, title: str) -> Figure:
    fig = Figure(figsize=(3.6 * len(panels), 7.4), layout="constrained")
    axes = fig.subplots(2, len(panels), squeeze=False)
    for j, (scene, record, reduced, projected, chaotic, heading) in enumerate(panels):
        _draw_regular_over_chaotic(axes[0, j], projected, chaotic, "paper", heading)
        _draw_regular_over_chaotic(
            axes[1, j], reduced, chaotic, "reduced", f"reduced: {100 * record['chaotic_fraction']:.0f}% chaotic (grey)"
        )
        plotting.draw_reduced_bounds(axes[1, j], scene, ENERGY, ANGULAR_MOMENTUM)
        if j:
            axes[0, j].set_ylabel("")
            axes[1, j].set_ylabel("")
    fig.suptitle(title)
    return fig


def make_paper_figures(settings: Settings, save, bar) -> list:
    """Figs. 1-3, the spiral column, the ell and inertia scans and Fig. 2's orbits in the reduced section; their
    records for ``summary["figures"]``."""
    figures = []

    def add_figure(name: str, fig: Figure, png: str, description: str, panels: list, t0: float) -> None:
        figures.append(figure_record(name, save(fig, png), description, panels, t0))

    # Fig. 1 and the spiral column: one orbit at ell = 1.
    t0 = time.perf_counter()
    scene1 = StickInCircle(R=R, ell=1.0)
    state1 = np.asarray(FIG1_STATE)
    orbit1 = run_orbit(scene1, state1, settings.fig1_collisions)
    fig = plotting.trajectory_figure(scene1, state1, orbit1, wall_at=5)
    fig.suptitle("Fig. 1: a trajectory of the stick's centre, R = 2, ell = 1")
    add_figure(
        "fig1",
        fig,
        "fig1_trajectory.png",
        "configuration space: centre's path, stick at contacts, rotating wall at contact 6",
        [_panel("R = 2, ell = 1", scene1, state1, orbit1)],
        t0,
    )
    bar.advance("Fig. 1")

    t0 = time.perf_counter()
    fig = plotting.spiral_column_figure(scene1, state1, orbit1, collisions=min(7, settings.fig1_collisions))
    add_figure(
        "spiral_column",
        fig,
        "spiral_column.png",
        "the Fig. 1 orbit as a point moving in straight lines inside the spiral column",
        [_panel("R = 2, ell = 1", scene1, state1, orbit1)],
        t0,
    )
    bar.advance("spiral column")

    # Fig. 2: one regular and one chaotic orbit at ell = 1.9.
    t0 = time.perf_counter()
    scene2 = StickInCircle(R=R, ell=1.9)
    states2 = _fig2_states(scene2)
    orbit2, divergence2 = _with_twins(scene2, states2, settings.fig2_collisions)
    projected2 = np.asarray(paper_section(scene2, orbit2.state))
    reduced2 = np.asarray(reduced_section(scene2, orbit2.state))
    thick2 = _thicknesses(reduced2)
    thick2_projected = _thicknesses(projected2)

    fig = Figure(figsize=(7, 5.5), layout="constrained")
    ax = fig.add_subplot()
    colors = ["tab:blue", "tab:red"]
    labels = ["regular", "chaotic"]
    plotting.draw_section(
        ax,
        projected2,
        "paper",
        colors=colors,
        labels=labels,
        markersize=1.2,
        title=f"Fig. 2: projected section, R = 2, ell = 1.9, {settings.fig2_collisions} collisions each",
    )
    add_figure(
        "fig2",
        fig,
        "fig2_projected_section.png",
        "the paper's projection (L_z against phi_c) of one regular and one chaotic orbit",
        [
            _panel(
                "R = 2, ell = 1.9",
                scene2,
                states2,
                orbit2,
                orbit_kinds=labels,
                reduced_thickness=thick2,
                projected_thickness=thick2_projected,
                twin_divergence=divergence2.tolist(),
            )
        ],
        t0,
    )
    bar.advance("Fig. 2")

    # Fig. 3: the static lens.
    t0 = time.perf_counter()
    scene3 = StickInCircle(R=R, ell=1.5, inertia=float("inf"))
    states3 = section_seeds(scene3, settings.lens_orbits, ENERGY)
    orbit3, divergence3 = _with_twins(scene3, states3, settings.lens_collisions)
    fig = Figure(figsize=(12, 5.2), layout="constrained")
    ax_paper, ax_birkhoff = fig.subplots(1, 2)
    chaotic3 = divergence3 > CHAOTIC_DIVERGENCE
    _draw_regular_over_chaotic(
        ax_paper,
        np.asarray(paper_section(scene3, orbit3.state)),
        chaotic3,
        "paper",
        "the paper's axes (chaotic orbits grey)",
    )
    _draw_regular_over_chaotic(
        ax_birkhoff,
        np.asarray(reduced_section(scene3, orbit3.state)),
        chaotic3,
        "birkhoff",
        "Birkhoff coordinates of the lens",
    )
    plotting.draw_reduced_bounds(ax_birkhoff, scene3)
    fig.suptitle(
        f"Fig. 3: infinite inertia (static lens), R = 2, ell = 1.5, "
        f"{settings.lens_orbits} orbits x {settings.lens_collisions} collisions"
    )
    add_figure(
        "fig3",
        fig,
        "fig3_lens_section.png",
        "static lens: the paper's projection (a complete section here) and Birkhoff coordinates",
        [_panel("R = 2, ell = 1.5, I = inf", scene3, states3, orbit3, chaotic_fraction=float(np.mean(chaotic3)))],
        t0,
    )
    bar.advance("Fig. 3")

    # The ell scan.
    t0 = time.perf_counter()
    panels, records, ell_panels = [], [], {}
    for ell in settings.ell_values:
        scene = StickInCircle(R=R, ell=ell)
        record, reduced, projected, chaotic = _section_panel(scene, settings, f"ell = {ell:g}")
        ell_panels[ell] = (record, reduced, projected, chaotic)
        panels.append((scene, record, reduced, projected, chaotic, f"ell = {ell:g}, I = M ell^2"))
        records.append(record)
    background = panels[0] if settings.ell_values and settings.ell_values[0] == 1.9 else None
    fig = _scan_figure(
        panels,
        f"R = 2, E = 1/2, L = 0: {settings.section_orbits} orbits x {settings.section_collisions} collisions per panel",
    )
    add_figure(
        "ell_scan", fig, "ell_scan.png", "shorter sticks: projected (top) and reduced (bottom) sections", records, t0
    )
    bar.advance("ell scan")

    # The inertia scan.
    t0 = time.perf_counter()
    panels, records = [], []
    ell = settings.inertia_ell
    for factor in settings.inertia_factors:
        scene = StickInCircle(R=R, ell=ell, inertia=factor * ell**2)
        name = "M ell^2" if factor == 1.0 else f"M ell^2 / {1 / factor:g}"
        if factor == 1.0 and ell in ell_panels:  # the same orbits as the ell scan's panel
            record, reduced, projected, chaotic = ell_panels[ell]
            record = dict(record, label=f"I = {name}")
        else:
            record, reduced, projected, chaotic = _section_panel(scene, settings, f"I = {name}")
        panels.append((scene, record, reduced, projected, chaotic, f"ell = {ell:g}, I = {name}"))
        records.append(record)
    fig = _scan_figure(panels, f"R = 2, ell = {ell:g}, E = 1/2, L = 0: lighter sticks")
    add_figure(
        "inertia_scan",
        fig,
        "inertia_scan.png",
        "smaller moment of inertia: projected (top) and reduced (bottom) sections",
        records,
        t0,
    )
    bar.advance("inertia scan")

    # The Fig. 2 orbits in the reduced section, beside the projection.
    t0 = time.perf_counter()
    fig = Figure(figsize=(12, 5.2), layout="constrained")
    ax_projected, ax_reduced = fig.subplots(1, 2)
    if background is not None:
        plotting.draw_section(ax_projected, background[3], "paper", colors="0.8", markersize=0.5)
        plotting.draw_section(ax_reduced, background[2], "reduced", colors="0.8", markersize=0.5)
    plotting.draw_section(
        ax_projected,
        projected2,
        "paper",
        colors=colors,
        labels=labels,
        markersize=1.2,
        title="projected (the paper's axes)",
    )
    plotting.draw_section(
        ax_reduced,
        reduced2,
        "reduced",
        colors=colors,
        labels=labels,
        markersize=1.2,
        title=f"reduced (E = 1/2, L = 0): thickness {thick2[0]:.3f} and {thick2[1]:.2f}",
    )
    plotting.draw_reduced_bounds(ax_reduced, scene2, ENERGY, ANGULAR_MOMENTUM)
    fig.suptitle("Fig. 2's orbits (R = 2, ell = 1.9); grey: other orbits of the same E and L")
    add_figure(
        "fig2_reduced",
        fig,
        "fig2_reduced_vs_projected.png",
        "the Fig. 2 orbits in the reduced section (a curve and an area) beside the projection",
        [figures[2]["panels"][0]],
        t0,
    )
    bar.advance("reduced vs projected")
    return figures
