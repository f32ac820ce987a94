"""What ``jaxbill figures`` computes and writes: the paper's figures, its scans, and the reduced section.

``make_figures(out_dir)`` runs every figure with built-in defaults and writes,
into ``out_dir``:

* ``fig1_trajectory.png``: Fig. 1, R = 2, ell = 1: the centre's path, the
  stick at its contacts, the rotating lens wall at one contact;
* ``fig2_projected_section.png``: Fig. 2, R = 2, ell = 1.9: one regular and
  one chaotic orbit, 1e4 collisions each, in the paper's axes (L_z against
  phi_c in units of pi);
* ``fig3_lens_section.png``: Fig. 3, I = inf, R = 2, ell = 1.5, many orbits,
  in the paper's axes and in the lens's Birkhoff coordinates;
* ``ell_scan.png``: ell = 1.9, 1.5, 1.1, 0.5, 0.1 (I = M ell^2): projected
  section above, reduced section below;
* ``inertia_scan.png``: ell = 1.9, I = M ell^2 times 1, 1/100, 1/200, the same
  two rows;
* ``fig2_reduced_vs_projected.png``: the Fig. 2 orbits in the reduced section
  (at their common E and L) beside the projection;
* ``spiral_column.png``: the Fig. 1 orbit as a point in the spiral column;
* ``walls_sections.png``: the stick between two flat walls (ell = 1,
  I = M ell^2), h = 1.5, 2.05, 2.5, 3, 4, 8: the 2D floor section
  ``(theta mod pi, p)`` (top) and the 3D reduced section at ``I w_z = 0.6
  sqrt(2 I E')`` (bottom), many orbits each, chaotic ones grey;
* ``walls_3d_flights.png``: one start point's flights in the ``(kappa theta, z)``
  plane: the 2D stick (straight), the same orbit run in 3D (``L_z = 0``:
  straight, the polar angle folded at the vertical) and a 3D stick spinning
  about the vertical (curved, kept off the vertical by ``L_z^2 / (2 I sin^2
  theta)``);
* ``ellipse.png``: the stick in an ellipse (``a = 2, b = 1.3``): one
  trajectory of a stick (``ell = 0.6``) with the stick drawn at its contacts,
  the point's Birkhoff section ``(s, p)`` (area-preserving; the elliptic
  billiard is integrable, so every orbit draws a curve) and the stick's
  ``(s, p)`` of the touching end (a projection); recorded under
  ``"ellipse"``;
* ``compositions.png``: bodies in tables (``jb.BodyInTable``): a triangle
  in a stadium, a dumbbell of masses 1:3 in an ellipse, a square in a
  circle, a point in the stadium and an elliptic coin between two walls;
  one orbit each from a Liouville start at ``E = 1/2`` (the coin's on its
  floor section, tossed sideways), the table, the centre's path and the
  body at some of its collisions; recorded under ``"compositions"``;
* ``summary.json`` and ``summary.txt``: every panel's parameters, orbit and
  collision counts, worst invariant drifts, chaotic fraction, start states
  (json), timings. The wall scenes' panels are under ``"walls"`` (not
  ``"figures"``), with their own drifts: relative energy, and the conserved
  momentum (``M vx`` in 2D, ``L_z`` in 3D) in units of ``sqrt(2 M E')`` and
  ``sqrt(2 I E')``.

All orbits of a section start on the section itself (``section_seeds`` /
``section_state``) at energy ``E = 1/2`` and total angular momentum ``L = 0``
(what a stick started at rest in its spin with its centre moving through the
origin has), so every reduced-section panel holds one ``(E, L)``. The paper
gives no initial conditions; ``L = 0`` is the choice under which its projected
section shows tori at all (orbits with ``L != 0`` precess, and their
projection smears into bands; see notebook 03).

Drifts: ``energy_drift`` is ``max |E_j / E_0 - 1|`` over all collisions ``j``
and orbits of a panel, ``E_0`` each orbit's start; ``angular_momentum_drift``
is ``max |L_j - L_0| / (R sqrt(2 M E_0))`` (``L_0`` may be 0, so the drift is
measured against the largest angular momentum the energy allows at radius R);
none for the lens, whose orbital angular momentum is not conserved. An orbit
is counted as chaotic when it and a twin started with its velocity turned by
``1e-11`` rad end up more than ``1e-3`` apart (``is_chaotic`` in
``jaxbill._analysis.section_measures``: tori give ``< 1e-6``, chaos order one); with
seeds uniform in the area-preserving ``(s, p)``, the chaotic share of seeds
estimates the chaotic share of the section. Fig. 2's orbits also get their
``curve_thickness`` (a curve: below 0.01; an area: above 0.4).

The wall scenes (``jaxbill._scenes.walls.sections``) start every orbit on the floor
section at ``E' = 1/2`` (no horizontal motion), seeds uniform in the
area-preserving ``(theta, p)``; chaotic means a twin with ``(theta_dot,
eta_dot)`` turned by ``1e-11`` rad ends up more than ``1e-3`` away;
``median_separation_collisions`` records after how many collisions the twins
are ``1e-4`` apart and ``lyapunov_per_collision`` the median ``ln(1e7) / that``
over the chaotic orbits; ``regular_island_counts`` (3D) the pieces each regular
orbit draws on a 150 x 150 grid (``count_islands``).

``quick=True`` runs the same figures with few orbits and collisions (for
tests: under half a minute).
"""

from __future__ import annotations

import dataclasses
import json
import os
import sys
import time
from typing import cast

import jax
import numpy as np
from matplotlib.figure import Figure

from jaxbill import plotting
from jaxbill._analysis.chaos import sample_energy_shell
from jaxbill._analysis.section_measures import (
    CHAOTIC_DIVERGENCE,
    count_islands,
    curve_thickness,
    divergence,
    twin_states,
)
from jaxbill._engine.collision import orbit as run_orbit
from jaxbill._scenes.bodies.dumbbell import Dumbbell
from jaxbill._scenes.bodies.ellipse import EllipseBody
from jaxbill._scenes.bodies.point import PointBody
from jaxbill._scenes.bodies.polygon import PolygonBody
from jaxbill._scenes.body_in_table import BodyInTable
from jaxbill._scenes.body_sections import draw_orbit
from jaxbill._scenes.circle.scene import StickInCircle
from jaxbill._scenes.circle.sections import (
    half_corner_angle,
    paper_section,
    reduced_section,
    section_seeds,
    section_state,
)
from jaxbill._scenes.ellipse.scene import StickInEllipse
from jaxbill._scenes.ellipse.sections import draw_ellipse_orbit, ellipse_length
from jaxbill._scenes.protocols import Scene
from jaxbill._scenes.tables.circle import Circle
from jaxbill._scenes.tables.ellipse import Ellipse
from jaxbill._scenes.tables.flat import Strip
from jaxbill._scenes.tables.stadium import Stadium
from jaxbill._scenes.walls import sections as ws
from jaxbill._scenes.walls.scene_2d import StickBetweenWalls2D
from jaxbill._scenes.walls.scene_3d import StickBetweenWalls3D

ENERGY = 0.5
ANGULAR_MOMENTUM = 0.0
R = 2.0

FILES = (
    "fig1_trajectory.png",
    "fig2_projected_section.png",
    "fig3_lens_section.png",
    "ell_scan.png",
    "inertia_scan.png",
    "fig2_reduced_vs_projected.png",
    "spiral_column.png",
    "summary.json",
    "summary.txt",
)
# Written too, recorded under summary["walls"]: the stick between two flat walls.
WALLS_FILES = ("walls_sections.png", "walls_3d_flights.png")
WALLS_ELL = 1.0
# Written too, recorded under summary["ellipse"]: the stick in an ellipse.
ELLIPSE_FILES = ("ellipse.png",)
ELLIPSE_AXES = (2.0, 1.3)
ELLIPSE_ELL = 0.6
ELLIPSE_STATE = (0.1, 0.2, 0.3, 0.7, -0.4, 0.9)
WALLS_ENERGY = 0.5  # E': the energy without the (absent) horizontal motion
# Written too, recorded under summary["compositions"]: bodies in tables, one orbit each.
COMPOSITIONS_FILES = ("compositions.png",)
COMPOSITIONS_SEED = 11  # of each start's draw from the energy shell
COIN_START = (0.9, 0.2)  # (alpha, p) on the coin's floor section
COIN_SPREAD = 10.0  # the coin's sideways speed spreads its collisions over this length


@dataclasses.dataclass(frozen=True)
class Settings:
    """Sizes of the runs. ``Settings()`` is the full set; ``Settings.quick()`` the test-sized one."""

    fig1_collisions: int = 24
    fig2_collisions: int = 10_000
    section_orbits: int = 100
    section_collisions: int = 4_000
    lens_orbits: int = 100
    lens_collisions: int = 4_000
    ell_values: tuple = (1.9, 1.5, 1.1, 0.5, 0.1)
    inertia_ell: float = 1.9
    inertia_factors: tuple = (1.0, 0.01, 0.005)
    walls_h_values: tuple = (1.5, 2.05, 2.5, 3.0, 4.0, 8.0)
    walls_orbits: int = 40
    walls_collisions: int = 2_000
    walls_spin: float = 0.6  # I w_z of the 3D row, in units of sqrt(2 I E')
    walls_flight_h: float = 3.0
    walls_flight_collisions: int = 12
    ellipse_trajectory_collisions: int = 30
    ellipse_orbits: int = 24
    ellipse_collisions: int = 2_000
    compositions_collisions: int = 24
    compositions_bodies: int = 8  # bodies drawn per panel, at evenly spaced collisions
    dpi: int = 150
    quick: bool = False

    @classmethod
    def quick_settings(cls) -> Settings:
        return cls(
            fig2_collisions=600,
            section_orbits=6,
            section_collisions=300,
            lens_orbits=6,
            lens_collisions=300,
            walls_orbits=6,
            walls_collisions=300,
            ellipse_orbits=6,
            ellipse_collisions=300,
            compositions_collisions=12,
            compositions_bodies=6,
            dpi=60,
            quick=True,
        )


# Fig. 2's two orbits, as section points (s, p) at ell = 1.9, E = 1/2, L = 0:
# a torus of the big island round the stick bouncing along a diameter
# (s = R beta_max, the middle of the arc of P1), and an orbit in the chaotic
# layer near a lens corner.
FIG2_REGULAR = ("middle", 0.5)
FIG2_CHAOTIC = (0.05, 0.9)
FIG1_STATE = (0.3, -0.2, 0.4, 0.62, 0.55, 0.45)


class Progress:
    """A minimal progress bar on stderr (no dependency): ``[####......] 3/8 label  12.3 s``."""

    def __init__(self, total: int, enabled: bool = True, stream=None):
        self.total, self.done, self.enabled = total, 0, enabled
        self.stream = sys.stderr if stream is None else stream
        self.start = time.perf_counter()
        self.tty = getattr(self.stream, "isatty", lambda: False)()

    def show(self, label: str) -> None:
        if not self.enabled:
            return
        width = 24
        filled = int(width * self.done / self.total)
        elapsed = time.perf_counter() - self.start
        line = f"[{'#' * filled}{'.' * (width - filled)}] {self.done}/{self.total} {label:<38} {elapsed:6.1f} s"
        if self.tty:
            self.stream.write("\r" + line)
            if self.done == self.total:
                self.stream.write("\n")
        else:
            self.stream.write(line + "\n")
        self.stream.flush()

    def advance(self, label: str) -> None:
        self.done += 1
        self.show(label)


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
    """Worst energy and angular-momentum drift of a batch of orbits (see the module docstring)."""
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
        "energy": _common_value(scene.energy(batch)),
        "angular_momentum": (
            _common_value(scene.angular_momentum(batch)) if _conserves_angular_momentum(scene) else None
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


def _common_value(values):
    values = np.asarray(values, dtype=np.float64)
    if np.allclose(values, values.flat[0], rtol=1e-12, atol=1e-12):
        return round(float(values.flat[0]), 12)
    return values.tolist()


def _with_twins(scene, states0, n):
    """Run orbits and their twins in one batch; return (orbit of the originals, divergence per orbit)."""
    states0 = np.asarray(states0)
    both = run_orbit(scene, np.concatenate([states0, twin_states(states0)]), n)
    count = len(states0)
    orb = jax.tree.map(lambda leaf: leaf[:count], both)
    return orb, divergence(scene, both.state[:count], both.state[count:], states0)


TWIN_DELTA = 1e-11  # twin_states' default: the velocity turn of each orbit's twin


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


# -- the stick between two flat walls ------------------------------------------


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
        "energy": _common_value(internal0),
        "spin": _common_value(float(scene.inertia) * states0[:, 11]) if three else None,
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


def _walls_figures(settings: Settings, save, bar) -> list:
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
    out.append(
        {
            "name": "walls_sections",
            "file": path,
            "description": "stick between walls: 2D floor sections (top) and 3D reduced sections at L_z != 0 "
            "(bottom) as h varies",
            "panels": records,
            "seconds": time.perf_counter() - t0,
        }
    )
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
        out.append(
            {
                "name": "walls_3d_flights",
                "file": path,
                "description": "flights in the (ell theta, z) plane: 2D, 3D with L_z = 0, 3D with L_z != 0",
                "panels": records,
                "seconds": time.perf_counter() - t0,
            }
        )
    bar.advance("walls: 3D flights")
    return out


def _ellipse_figures(settings: Settings, save, bar) -> list:
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
    return [
        {
            "name": "ellipse",
            "file": path,
            "panels": records,
            "seconds": time.perf_counter() - t0,
            "description": "stick in an ellipse: one trajectory, the point's Birkhoff section, the stick's",
        }
    ]


def composition_scenes() -> list[tuple[str, str, str, BodyInTable]]:
    """The compositions of ``compositions.png``: ``(label, body, table, scene)``, body and table as written."""
    stadium = Stadium(1.0, 1.0)
    return [
        (
            "triangle in a stadium",
            "PolygonBody.regular(3, 0.3)",
            "Stadium(1, 1)",
            BodyInTable(PolygonBody.regular(3, 0.3), stadium),
        ),
        (
            "dumbbell 1:3 in an ellipse",
            "Dumbbell.from_masses(0.25, 0.75, 1)",
            "Ellipse(2, 1.3)",
            BodyInTable(Dumbbell.from_masses(0.25, 0.75, 1.0), Ellipse(2.0, 1.3)),
        ),
        (
            "square in a circle",
            "PolygonBody.regular(4, 0.5)",
            "Circle(1)",
            BodyInTable(PolygonBody.regular(4, 0.5), Circle(1.0)),
        ),
        ("point in the stadium", "PointBody()", "Stadium(1, 1)", BodyInTable(PointBody(), stadium)),
        ("coin between walls", "EllipseBody(1, 0.5)", "Strip(4)", BodyInTable(EllipseBody(1.0, 0.5), Strip(4.0))),
    ]


def _as_scene(scene: BodyInTable) -> Scene:
    """The scene as the engine's protocol: a body in a table names its gaps and walls by properties (they depend on
    its parts), which pyright does not match to the protocol's class constants."""
    return cast(Scene, scene)


def _composition_start(scene: BodyInTable, n: int) -> np.ndarray:
    """A Liouville start at ``E = 1/2``; between walls, one on the floor section tossed sideways (``vx`` changes
    nothing else, so it is chosen to spread the ``n`` collisions over ``COIN_SPREAD``)."""
    if "floor" not in scene.sections:
        states, _ = sample_energy_shell(_as_scene(scene), 1, energy=ENERGY, seed=COMPOSITIONS_SEED)
        return states[0]
    state = np.array(scene.section_state(np.asarray(COIN_START), energy=ENERGY))
    upright = run_orbit(_as_scene(scene), state, n)
    state[3] = COIN_SPREAD / float(np.asarray(upright.t)[-1])
    return state


def _compositions_figures(settings: Settings, save, bar) -> list:
    """``compositions.png``: one orbit of each composition in configuration space; records for
    ``summary["compositions"]``."""
    t0 = time.perf_counter()
    n, bodies = settings.compositions_collisions, settings.compositions_bodies
    compositions = composition_scenes()
    fig = Figure(figsize=(15, 9), layout="constrained")
    # the strip is wide: the coin gets two places in the second row
    axes = fig.subplot_mosaic([[0, 1, 2], [3, 4, 4]])
    records = []
    for k, (label, body, table, scene) in enumerate(compositions):
        ax = axes[k]
        state0 = _composition_start(scene, n)
        orb = jax.device_get(run_orbit(_as_scene(scene), state0, n))
        draw_orbit(ax, scene, state0, orb, "tab:blue", body_every=max(1, n // bodies))
        ax.set_title(f"{label}\n{body} in {table}", fontsize="medium")
        energies = np.asarray(scene.energy(orb.state))
        records.append(
            {
                "label": label,
                "body": body,
                "table": table,
                "kind": scene.kind,
                "energy": float(np.asarray(scene.energy(state0))),
                "collisions": n,
                "missed_or_failed": int(np.sum(np.asarray(orb.contact) == 0)),
                "energy_drift": float(np.max(np.abs(energies / float(np.asarray(scene.energy(state0))) - 1.0))),
                "state0": state0.tolist(),
            }
        )
    fig.suptitle(
        f"Bodies in tables: the centre's path over {n} collisions and the body at one collision in "
        f"{max(1, n // bodies)} (mass 1, E = 1/2)"
    )
    path = save(fig, COMPOSITIONS_FILES[0])
    bar.advance("compositions")
    return [
        {
            "name": "compositions",
            "file": path,
            "panels": records,
            "seconds": time.perf_counter() - t0,
            "description": "bodies in tables: a triangle, a 1:3 dumbbell, a square, a point and a coin, one orbit each",
        }
    ]


def _embed_2d(states2d) -> np.ndarray:
    """2D ``[x, z, th, vx, vz, om]`` as 3D states in the ``x``-``z`` plane."""
    x, z, th, vx, vz, om = np.moveaxis(np.asarray(states2d, dtype=np.float64), -1, 0)
    zero = np.zeros_like(x)
    return np.stack([x, zero, z, np.sin(th), zero, np.cos(th), vx, zero, vz, zero, om, zero], axis=-1)


def _studies_figures(out_dir: str, quick: bool, bar) -> list:
    """``small_stick_law.png`` and ``arnold_web.png`` from the studies' stored data (notebooks 09 and 10).

    Both are drawn from ``notebooks/data/`` (the measurements take minutes to
    tens of minutes: ``notebooks/data/make_*_data.py``); where a file is
    missing (an install without the repository's notebooks) the figure is
    skipped and the summary says so.
    """
    from jaxbill.studies import arnold_web, small_stick

    records = []
    for name, data_file, draw in (
        ("small_stick_law", small_stick.DATA_FILE, lambda: small_stick.small_stick_figure(out_dir)),
        ("arnold_web", arnold_web.DATA_PATH, lambda: arnold_web.arnold_web_figure(out_dir, quick=quick)),
    ):
        t0 = time.perf_counter()
        if data_file.exists():
            records.append({"name": name, "file": os.path.basename(str(draw())), "seconds": time.perf_counter() - t0})
        else:
            records.append({"name": name, "file": None, "skipped": f"no stored data at {data_file}"})
        bar.advance(name.replace("_", " "))
    return records


def make_figures(
    out_dir: str = "figures", *, quick: bool = False, progress: bool = True, settings: Settings | None = None
) -> dict:
    """Compute and write every figure and the summary into ``out_dir``; return the summary.

    Args:
        out_dir: folder to write into (created if missing).
        quick: small runs (for tests) instead of the full defaults.
        progress: show a progress bar on stderr.
        settings: override the run sizes (default ``Settings()`` or
            ``Settings.quick_settings()``).
    """
    if settings is None:
        settings = Settings.quick_settings() if quick else Settings()
    os.makedirs(out_dir, exist_ok=True)
    steps = 14
    bar = Progress(steps, progress)
    bar.show("starting (compiling the collision map)")
    started = time.perf_counter()
    figures = []

    def save(fig: Figure, name: str) -> str:
        path = os.path.join(out_dir, name)
        fig.savefig(path, dpi=settings.dpi)
        return name

    def add_figure(name: str, fig: Figure, png: str, description: str, panels: list, t0: float) -> None:
        figures.append(
            {
                "name": name,
                "file": save(fig, png),
                "description": description,
                "panels": panels,
                "seconds": time.perf_counter() - t0,
            }
        )

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

    walls_figures = _walls_figures(settings, save, bar)
    ellipse_figures = _ellipse_figures(settings, save, bar)
    compositions_figures = _compositions_figures(settings, save, bar)
    studies_figures = _studies_figures(out_dir, settings.quick, bar)

    all_panels = [p for f in figures for p in f["panels"]]
    summary = {
        "jaxbill_figures": 1,
        "quick": settings.quick,
        "settings": dataclasses.asdict(settings),
        "total_seconds": time.perf_counter() - started,
        "worst_energy_drift": max(p["energy_drift"] for p in all_panels),
        "worst_angular_momentum_drift": max(
            p["angular_momentum_drift"] for p in all_panels if p["angular_momentum_drift"] is not None
        ),
        "total_collisions": sum(
            p["collisions"] for f in figures if f["name"] not in ("spiral_column", "fig2_reduced") for p in f["panels"]
        ),
        "figures": figures,
        "walls": walls_figures,
        "ellipse": ellipse_figures,
        "compositions": compositions_figures,
        "studies": studies_figures,
        "walls_worst_energy_drift": max((p["energy_drift"] for f in walls_figures for p in f["panels"]), default=None),
        "walls_worst_momentum_drift": max(
            (p["momentum_drift"] for f in walls_figures for p in f["panels"]), default=None
        ),
    }
    with open(os.path.join(out_dir, "summary.json"), "w") as handle:
        json.dump(summary, handle, indent=1)
    with open(os.path.join(out_dir, "summary.txt"), "w") as handle:
        handle.write(summary_text(summary))
    bar.advance("summary")
    return summary


def summary_text(summary: dict) -> str:
    """The human-readable ``summary.txt``."""
    lines = [
        f"jaxbill figures ({'quick' if summary['quick'] else 'full'} run): "
        f"{summary['total_collisions']} collisions in {summary['total_seconds']:.1f} s",
        f"worst relative energy drift {summary['worst_energy_drift']:.2e}; "
        f"worst angular-momentum drift {summary['worst_angular_momentum_drift']:.2e} (units of R sqrt(2 M E))",
        "",
        f"{'file':<31} {'panel':<26} {'inertia':>9} {'orbits':>6} {'coll/orbit':>10} "
        f"{'dE/E':>9} {'dL':>9} {'chaotic':>7}",
    ]
    for figure in summary["figures"]:
        for panel in figure["panels"]:
            inertia = panel["scene"]["inertia"]
            inertia = inertia if isinstance(inertia, str) else f"{inertia:.4g}"
            dl = panel["angular_momentum_drift"]
            chaotic = panel.get("chaotic_fraction")
            lines.append(
                f"{figure['file']:<31} {panel['label']:<26} {inertia:>9} {panel['orbits']:>6} "
                f"{panel['collisions_per_orbit']:>10} {panel['energy_drift']:>9.1e} "
                f"{'-' if dl is None else f'{dl:.1e}':>9} {'-' if chaotic is None else f'{chaotic:.2f}':>7}"
            )
    lines += [
        "",
        "Energy E = 1/2 and total angular momentum L = 0 for every section orbit; R = 2, mass 1.",
        "dE/E = max |E_j/E_0 - 1|; dL = max |L_j - L_0| / (R sqrt(2 M E_0)) (none for the lens: L not conserved).",
        "chaotic = share of orbits that part from a twin turned by 1e-11 rad by more than 1e-3 (tori: < 1e-6).",
        "",
    ]
    for figure in summary["figures"]:
        lines.append(f"{figure['file']}: {figure['description']} ({figure['seconds']:.1f} s)")
    if summary.get("walls"):
        lines += [
            "",
            "Stick between two flat walls: ell = 1, mass 1, I = M ell^2, E' = 1/2 (no horizontal motion).",
            f"{'file':<23} {'panel':<24} {'orbits':>6} {'coll/orbit':>10} {'floor':>7} {'flat':>5} "
            f"{'dE/E':>9} {'dP':>9} {'chaotic':>7} {'apart':>6} {'lyap':>6}",
        ]
        for figure in summary["walls"]:
            for panel in figure["panels"]:
                lyap = panel["lyapunov_per_collision"]
                lines.append(
                    f"{figure['file']:<23} {panel['label']:<24} {panel['orbits']:>6} "
                    f"{panel['collisions_per_orbit']:>10} "
                    f"{panel['floor_collisions']:>7} {panel['several_contacts']:>5} {panel['energy_drift']:>9.1e} "
                    f"{panel['momentum_drift']:>9.1e} {panel['chaotic_fraction']:>7.2f} "
                    f"{panel['median_separation_collisions']:>6.0f} {'-' if lyap is None else f'{lyap:.2f}':>6}"
                )
        lines += [
            "floor = floor collisions (section points); flat = contacts 2 (flat landings, kinks); "
            "dP = max drift of M vx (2D) or L_z (3D) in units of sqrt(2 M E') or sqrt(2 I E');",
            "chaotic = share of orbits that part from a twin ((theta_dot, eta_dot) turned by 1e-11 rad) by "
            "more than 1e-3; apart = median collisions until 1e-4 apart; lyap = median ln(1e7)/apart "
            "of the chaotic ones (per collision).",
            "",
        ]
        for figure in summary["walls"]:
            lines.append(f"{figure['file']}: {figure['description']} ({figure['seconds']:.1f} s)")
    for figure in summary.get("ellipse", []):
        lines += ["", f"{figure['file']}: {figure['description']} ({figure['seconds']:.1f} s)"]
        for panel in figure["panels"]:
            lines.append(
                f"  {panel['label']:<34} {panel['orbits']:>4} orbits x {panel['collisions_per_orbit']} "
                f"collisions, dE/E {panel['energy_drift']:.1e}"
            )
    for figure in summary.get("compositions", []):
        lines += ["", f"{figure['file']}: {figure['description']} ({figure['seconds']:.1f} s)"]
        for panel in figure["panels"]:
            lines.append(
                f"  {panel['label']:<28} {panel['body']} in {panel['table']}: {panel['collisions']} collisions, "
                f"dE/E {panel['energy_drift']:.1e}"
            )
    for figure in summary.get("studies", []):
        if figure["file"] is None:
            lines += ["", f"{figure['name']}: skipped ({figure['skipped']})"]
        else:
            lines += ["", f"{figure['file']}: drawn from the stored measurement ({figure['seconds']:.1f} s)"]
    return "\n".join(lines) + "\n"
