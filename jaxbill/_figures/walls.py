"""The stick between two flat walls: the 2D and 3D floor sections as the gap varies, one start's flights, and
the records of their panels (drifts of the conserved momentum, chaotic share, twin separation)."""

from __future__ import annotations

import time

import jax
import numpy as np
from matplotlib.figure import Figure

from jaxbill import plotting
from jaxbill._analysis.section_measures import CHAOTIC_DIVERGENCE, count_islands
from jaxbill._figures.common import TWIN_DELTA, Settings, common_value, figure_record
from jaxbill._scenes.walls import sections as ws
from jaxbill._scenes.walls.scene_2d import StickBetweenWalls2D
from jaxbill._scenes.walls.scene_3d import StickBetweenWalls3D

# Recorded under summary["walls"].
WALLS_FILES = ("walls_sections.png", "walls_3d_flights.png")
WALLS_ELL = 1.0
WALLS_ENERGY = 0.5  # E': the energy without the (absent) horizontal motion


def _walls_scene_record(scene) -> dict:
    return {
        "h": float(scene.h),
        "ell": float(scene.ell),
        "mass": float(scene.mass),
        "inertia": float(scene.inertia),
        "kind": scene.kind,
        "dimension": 3 if scene.state_size == 12 else 2,
    }


def _walls_invariants(scene, states):
    """Energy and conserved momentum (``M vx`` in 2D, ``L_z`` in 3D) in NumPy: ``(E, P, E')``."""
    states = np.asarray(states)
    mass, inertia = float(scene.mass), float(scene.inertia)
    if scene.state_size == 12:
        v, w = states[..., 6:9], states[..., 9:12]
        energy = 0.5 * mass * np.sum(v * v, axis=-1) + 0.5 * inertia * np.sum(w * w, axis=-1)
        internal = 0.5 * mass * v[..., 2] ** 2 + 0.5 * inertia * np.sum(w * w, axis=-1)
        momentum = mass * (states[..., 0] * v[..., 1] - states[..., 1] * v[..., 0]) + inertia * w[..., 2]
    else:
        energy = 0.5 * mass * (states[..., 3] ** 2 + states[..., 4] ** 2) + 0.5 * inertia * states[..., 5] ** 2
        internal = 0.5 * mass * states[..., 4] ** 2 + 0.5 * inertia * states[..., 5] ** 2
        momentum = mass * states[..., 3]
    return energy, momentum, internal


def _walls_panel(label, scene, states0, orb, points, distances, **extra):
    """One wall-scene panel's record (counts, drifts, chaotic share, twin separation) and its chaotic mask."""
    states0 = np.asarray(states0)
    contact = np.asarray(orb.contact)
    energy, momentum, _ = _walls_invariants(scene, orb.state)
    e0, momentum0, internal0 = _walls_invariants(scene, states0)
    energy_drift = float(np.max(np.abs(energy / e0[:, None] - 1.0)))
    three = scene.state_size == 12
    unit = np.sqrt(2.0 * (float(scene.inertia) if three else float(scene.mass)) * e0)
    n = contact.shape[1]
    divergence_ = np.max(distances[:, -max(1, n // 10) :], axis=1)
    chaotic = divergence_ > CHAOTIC_DIVERGENCE
    separation = ws.separation_collisions(distances)
    rates = np.log(1e-4 / TWIN_DELTA) / separation[chaotic & np.isfinite(separation)]
    finite = np.all(np.isfinite(np.asarray(points)), axis=-1)
    record = {
        "label": label,
        "scene": _walls_scene_record(scene),
        "energy": common_value(internal0),
        "spin": common_value(float(scene.inertia) * states0[:, 11]) if three else None,
        "orbits": len(states0),
        "collisions_per_orbit": n,
        "collisions": len(states0) * n,
        "floor_collisions": int(np.sum(finite)),
        "several_contacts": int(np.sum(contact == 2)),
        "missed_or_failed": int(np.sum(contact == 0)),
        "energy_drift": energy_drift,
        "conserved_momentum": "L_z" if three else "M vx",
        "momentum_drift": float(np.max(np.abs(momentum - momentum0[:, None]) / unit[:, None])),
        "chaotic_fraction": float(np.mean(chaotic)),
        "median_separation_collisions": float(np.median(separation)),
        "lyapunov_per_collision": float(np.median(rates)) if len(rates) else None,
        "twins": True,
        "twin_delta": TWIN_DELTA,
    }
    record.update(extra)
    record["states0"] = states0.tolist()
    return record, chaotic


def _island_counts(scene, points, chaotic, energy, spin) -> list[int]:
    """Pieces drawn by each regular orbit on a 150 x 150 grid of the section (``count_islands``)."""
    top = float(np.nanmax(np.asarray(ws.floor_section_bound(scene, np.linspace(0.0, np.pi, 401), energy, spin))))
    extent = ((0.0, np.pi), (-top, top))
    return [count_islands(p, bins=(150, 150), extent=extent) for p in np.asarray(points)[~chaotic]]


def _embed_2d(states2d) -> np.ndarray:
    """2D ``[x, z, th, vx, vz, om]`` as 3D states in the ``x``-``z`` plane."""
    x, z, th, vx, vz, om = np.moveaxis(np.asarray(states2d, dtype=np.float64), -1, 0)
    zero = np.zeros_like(x)
    return np.stack([x, zero, z, np.sin(th), zero, np.cos(th), vx, zero, vz, zero, om, zero], axis=-1)


def make_walls_figures(settings: Settings, save, bar) -> list:
    """``walls_sections.png`` and ``walls_3d_flights.png``; their records for ``summary["walls"]``."""
    out = []
    t0 = time.perf_counter()
    energy = WALLS_ENERGY
    count, n = settings.walls_orbits, settings.walls_collisions
    hs = settings.walls_h_values
    fig = Figure(figsize=(3.4 * len(hs), 7.0), layout="constrained")
    axes = fig.subplots(2, len(hs), squeeze=False)
    records, flights = [], {}
    for j, h in enumerate(hs):
        scene2, scene3 = StickBetweenWalls2D(h, WALLS_ELL), StickBetweenWalls3D(h, WALLS_ELL)
        spin = settings.walls_spin * float(np.sqrt(2.0 * float(scene3.inertia) * energy))
        theta3, p3 = ws.floor_seed_points(scene3, count, energy, spin)
        theta2, p2 = ws.floor_seed_points(scene2, count, energy)
        # The 2D seeds start at the 3D row's first section point: the flights figure compares them.
        theta2[0], p2[0] = theta3[0], p3[0]
        seeds3 = np.asarray(ws.floor_state(scene3, theta3, p3, energy, spin))
        seeds2 = np.asarray(ws.floor_state(scene2, theta2, p2, energy))

        orb2, dist2 = ws.orbits_with_twin_distances(scene2, seeds2, n, TWIN_DELTA)
        points2 = np.asarray(ws.floor_section(scene2, orb2.state, orb2.contact))
        record2, chaotic2 = _walls_panel(f"2D, h = {h:g}", scene2, seeds2, orb2, points2, dist2)
        orb3, dist3 = ws.orbits_with_twin_distances(scene3, seeds3, n, TWIN_DELTA)
        points3 = np.asarray(ws.reduced_wall_section(scene3, orb3.state, orb3.contact))
        record3, chaotic3 = _walls_panel(f"3D, h = {h:g}, L_z != 0", scene3, seeds3, orb3, points3, dist3)
        record3["regular_island_counts"] = _island_counts(scene3, points3, chaotic3, energy, spin)
        records += [record2, record3]
        if h == settings.walls_flight_h:
            flights.update(scene2=scene2, scene3=scene3, seeds2=seeds2, seeds3=seeds3, orb2=orb2, orb3=orb3)

        ax = axes[0, j]
        plotting.draw_floor_section(ax, points2[chaotic2][:, ::2], colors="0.75", markersize=0.6)
        if (~chaotic2).any():
            plotting.draw_floor_section(ax, points2[~chaotic2], markersize=0.8)
        plotting.draw_floor_section(ax, points2[0], colors="tab:red", markersize=1.0)
        plotting.draw_floor_section_bounds(ax, scene2, energy)
        ax.set_title(
            f"2D, h = {h:g}: {100 * record2['chaotic_fraction']:.0f}% chaotic\n"
            f"twins 1e-4 apart after {record2['median_separation_collisions']:.0f} collisions"
        )
        ax = axes[1, j]
        plotting.draw_floor_section(ax, points3[chaotic3][:, ::2], "3d", colors="0.75", markersize=0.6)
        if (~chaotic3).any():
            plotting.draw_floor_section(ax, points3[~chaotic3], "3d", markersize=0.9)
        plotting.draw_floor_section_bounds(ax, scene3, energy, spin)
        ax.set_title(f"3D, h = {h:g}, L_z != 0: {100 * record3['chaotic_fraction']:.0f}% chaotic")
        if j:
            axes[0, j].set_ylabel("")
            axes[1, j].set_ylabel("")
    fig.suptitle(
        f"Stick between walls (ell = 1, I = M ell^2, E' = 1/2), {count} orbits x {n} collisions per panel: "
        f"floor sections, 2D (top; red: one orbit) and 3D with I w_z = {settings.walls_spin:g} sqrt(2 I E') "
        "(bottom); grey: chaotic, colours: regular"
    )
    path = save(fig, WALLS_FILES[0])
    description = (
        "stick between walls: 2D floor sections (top) and 3D reduced sections at L_z != 0 (bottom) as h varies"
    )
    out.append(figure_record("walls_sections", path, description, records, t0))
    bar.advance("walls: sections")

    t0 = time.perf_counter()
    records = []
    if flights:
        scene2, scene3 = flights["scene2"], flights["scene3"]
        # The 2D orbits again in 3D, in the x-z plane (L_z = 0): the same batch size and length as the
        # 3D sections, so no new compilation.
        embedded = _embed_2d(flights["seeds2"])
        orb3z, dist3z = ws.orbits_with_twin_distances(scene3, embedded, n, TWIN_DELTA)
        points3z = np.asarray(ws.reduced_wall_section(scene3, orb3z.state, orb3z.contact))
        record3z, _ = _walls_panel(f"3D, h = {float(scene3.h):g}, L_z = 0", scene3, embedded, orb3z, points3z, dist3z)
        records.append(record3z)
        k = settings.walls_flight_collisions
        panels = [
            (scene2, flights["seeds2"][0], flights["orb2"], "2D: straight flights (theta unwrapped)"),
            (scene3, embedded[0], orb3z, "3D, L_z = 0: the same orbit (polar angle)"),
            (
                scene3,
                flights["seeds3"][0],
                flights["orb3"],
                f"3D, I w_z = {settings.walls_spin:g} sqrt(2 I E'): curved flights",
            ),
        ]
        fig = Figure(figsize=(15, 6.2), layout="constrained")
        axes = fig.subplots(1, 3)
        for ax, (scene, state0, orb, title) in zip(axes, panels):
            one = jax.tree.map(lambda leaf: np.asarray(leaf)[0], orb)  # the first orbit of the batch
            plotting.draw_wall_flights(ax, scene, state0, one, collisions=k)
            ax.set_title(title)
        fig.suptitle(
            f"The same start on the floor section, h = {float(scene2.h):g}, ell = 1: "
            f"{k} flights in the (kappa theta, z) plane (kappa = ell); dotted: the L_z barrier"
        )
        path = save(fig, WALLS_FILES[1])
        description = "flights in the (ell theta, z) plane: 2D, 3D with L_z = 0, 3D with L_z != 0"
        out.append(figure_record("walls_3d_flights", path, description, records, t0))
    bar.advance("walls: 3D flights")
    return out
