"""The scenes every generic test runs over, and valid starts for each.

One list, as a billiard package runs every table through one set of checks: the
hand-built scenes (the stick in a circle and its limits, the stick in an
ellipse, the stick between walls in 2D and 3D), bodies composed with tables
(points, a dumbbell of unequal masses, rigid polygons, the coin; circles,
ellipses, stadiums, polygons, the strip, a user's convex function) and the
field's standard tables. A new scene is added here; ``test_scene_contract.py``
and the generic tests of the drivers then run it.
"""

from __future__ import annotations

import numpy as np

import jaxbill as jb
from helpers import random_states

INF = float("inf")
TRIANGLE = [(0.0, 0.0), (0.6, 0.0), (0.15, 0.4)]
PENTAGON = [(1.1, -0.2), (0.7, 0.85), (-0.45, 0.95), (-1.05, 0.05), (-0.2, -0.95)]


def squircle(x, y):
    """A user's convex table: ``x^4 + y^4 <= 1``."""
    return x**4 + y**4 - 1.0


def hand_built() -> dict:
    """The scenes written by hand, each with its closed forms and its own section charts."""
    return {
        "rotor 1.9": jb.StickInCircle(R=2.0, ell=1.9),
        "rotor 1.0": jb.StickInCircle(R=2.0, ell=1.0),
        "lens": jb.StickInCircle(R=2.0, ell=1.5, inertia=INF),
        "circle": jb.StickInCircle(R=2.0, ell=0.0),
        "walls 2D": jb.StickBetweenWalls2D(h=3.0, ell=1.0),
        "walls 2D static": jb.StickBetweenWalls2D(h=3.0, ell=1.0, inertia=INF),
        "walls 3D": jb.StickBetweenWalls3D(h=3.0, ell=1.0),
        "ellipse": jb.StickInEllipse(a=2.0, b=1.4, ell=0.5),
        "ellipse static": jb.StickInEllipse(a=2.0, b=1.4, ell=0.5, inertia=INF),
        "ellipse point": jb.StickInEllipse(a=2.0, b=1.4, ell=0.0),
    }


def compositions() -> dict:
    """Bodies in tables, composed by ``jb.BodyInTable``."""
    return {
        "point in stadium": jb.BodyInTable(jb.PointBody(), jb.Stadium(1.0, 0.5)),
        "triangle in stadium": jb.BodyInTable(jb.PolygonBody(TRIANGLE), jb.Stadium(1.0, 0.8)),
        "dumbbell 1:3 in ellipse": jb.BodyInTable(jb.Dumbbell.from_masses(1.0, 3.0, 0.8), jb.Ellipse(2.0, 1.2)),
        "square in circle": jb.BodyInTable(jb.PolygonBody.regular(4, 0.3), jb.Circle(1.0)),
        "point in pentagon": jb.BodyInTable(jb.PointBody(), jb.Polygon(PENTAGON)),
        "static triangle in pentagon": jb.BodyInTable(jb.PolygonBody(TRIANGLE, inertia=INF), jb.Polygon(PENTAGON)),
        "coin between walls": jb.BodyInTable(jb.EllipseBody(0.4, 0.2), jb.Strip(1.0)),
        "dumbbell in a user's table": jb.BodyInTable(
            jb.Dumbbell(0.3), jb.ConvexTable(squircle, (-1.2, 1.2, -1.2, 1.2))
        ),
    }


def standard() -> dict:
    """The field's standard tables that are not convex: a point among dispersing walls, in a mushroom, in
    a periodic Lorentz gas."""
    obstacles = [jb.DiscObstacle((0.4, 0.0), 0.2), jb.EllipseObstacle((-0.4, 0.1), 0.2, 0.1)]
    return {
        "point in Sinai": jb.BodyInTable(jb.PointBody(), jb.Sinai(0.25)),
        "point in mushroom": jb.BodyInTable(jb.PointBody(), jb.Mushroom(1.0, 0.5, 1.0)),
        "point in Lorentz gas": jb.BodyInTable(jb.PointBody(), jb.LorentzGas(0.45, 1.0)),
        "point among obstacles": jb.BodyInTable(jb.PointBody(), jb.WithObstacles(jb.Circle(1.0), obstacles)),
    }


def catalogue() -> dict:
    return {**hand_built(), **compositions(), **standard()}


SCENES = catalogue()
NAMES = list(SCENES)


def start_states(scene, count: int, seed: int = 7) -> np.ndarray:
    """``count`` valid starts. A body in a table: its own Liouville sampler at energy 1/2. The hand-built
    scenes: random states inside (the stick in a circle from ``helpers.random_states``; in the ellipse,
    centres within 0.3 of the middle; between walls, heights 1.2-1.8), each carried through three
    collisions so that it starts just after one."""
    hand_built_classes = (jb.StickInCircle, jb.StickInEllipse, jb.StickBetweenWalls2D, jb.StickBetweenWalls3D)
    if not isinstance(scene, hand_built_classes):
        return np.asarray(jb.sample_energy_shell(scene, count, seed=seed)[0])
    rng = np.random.default_rng(seed)
    if isinstance(scene, jb.StickInCircle):
        return np.asarray(random_states(rng, count, 2.0, float(scene.ell), scene.kind))
    if isinstance(scene, jb.StickInEllipse):
        # Both ends (ell <= 0.5) well inside b = 1.4.
        radius, angle = 0.3 * np.sqrt(rng.uniform(size=count)), rng.uniform(-np.pi, np.pi, count)
        v = rng.normal(size=(count, 2))
        omega = rng.normal(size=count) if scene.body_turns else np.zeros(count)
        s = np.stack(
            [
                radius * np.cos(angle),
                radius * np.sin(angle),
                rng.uniform(-np.pi, np.pi, count),
                v[:, 0],
                v[:, 1],
                omega,
            ],
            axis=1,
        )
    elif scene.state_size == 6:
        z = rng.uniform(1.2, 1.8, count)
        theta = rng.uniform(-np.pi, np.pi, count)
        v = rng.normal(size=(count, 2))
        omega = rng.normal(size=count) if scene.body_turns else np.zeros(count)
        s = np.stack([np.zeros(count), z, theta, v[:, 0], v[:, 1], omega], axis=1)
    else:
        u = rng.normal(size=(count, 3))
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        w = rng.normal(size=(count, 3))
        w -= np.sum(w * u, axis=1, keepdims=True) * u
        c = np.stack([np.zeros(count), np.zeros(count), rng.uniform(1.2, 1.8, count)], axis=1)
        s = np.concatenate([c, u, rng.normal(size=(count, 3)), w], axis=1)
    return np.asarray(jb.orbit(scene, s, 3, driver="lockstep").state[:, -1])
