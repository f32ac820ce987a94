"""Bodies in tables (``BodyInTable``): one orbit of each composition in configuration space, and their records."""

from __future__ import annotations

import time
from typing import cast

import jax
import numpy as np
from matplotlib.figure import Figure

from jaxbill._analysis.chaos import sample_energy_shell
from jaxbill._engine.collision import orbit as run_orbit
from jaxbill._figures.common import ENERGY, Settings, figure_record
from jaxbill._scenes.bodies.dumbbell import Dumbbell
from jaxbill._scenes.bodies.ellipse import EllipseBody
from jaxbill._scenes.bodies.point import PointBody
from jaxbill._scenes.bodies.polygon import PolygonBody
from jaxbill._scenes.body_in_table import BodyInTable
from jaxbill._scenes.body_sections import draw_orbit
from jaxbill._scenes.protocols import Scene
from jaxbill._scenes.tables.circle import Circle
from jaxbill._scenes.tables.ellipse import Ellipse
from jaxbill._scenes.tables.flat import Strip
from jaxbill._scenes.tables.stadium import Stadium

# Recorded under summary["compositions"].
COMPOSITIONS_FILES = ("compositions.png",)
COMPOSITIONS_SEED = 11  # of each start's draw from the energy shell
COIN_START = (0.9, 0.2)  # (alpha, p) on the coin's floor section
COIN_SPREAD = 10.0  # the coin's sideways speed spreads its collisions over this length


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


def make_compositions_figures(settings: Settings, save, bar) -> list:
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
    description = "bodies in tables: a triangle, a 1:3 dumbbell, a square, a point and a coin, one orbit each"
    return [figure_record("compositions", path, description, records, t0)]
