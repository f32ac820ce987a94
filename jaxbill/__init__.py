"""jaxbill: rigid-body billiards in JAX.

Importing jaxbill switches JAX to float64 (``jax_enable_x64``): every collision
time and state is computed in double precision, and the library's accuracy
claims hold only there. It also asks XLA:CPU, before JAX's backend starts and
never over a choice the user made, to show one CPU device per core (so that a
batch uses every core) and, on x86-64, to compile each loop whole without fused
multiply-adds (one orbit's loop then runs as one native function rather than
a call per kernel at every collision, and every program still rounds alike, so
results stay bitwise reproducible). ``jaxbill._engine.backend`` says
why and how; ``jb.backend_settings()`` says what was set;
``JAXBILL_NO_XLA_SETTINGS=1`` sets nothing.

``import jaxbill`` itself is quick: it makes those settings (through JAX's
environment variables when JAX is not imported yet, so they hold whenever it
is) and loads the library, JAX with it, at the first use of a public name, so
that ``jaxbill --help`` answers at once.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from jaxbill._engine.backend import backend_settings, configure

configure()

# Each public name and the module that defines it; loaded on first use (``__getattr__``).
_PUBLIC: dict[str, tuple[str, ...]] = {
    "jaxbill._analysis.chaos": (
        "FiniteTimeLyapunov",
        "chaos_threshold",
        "chaotic_fraction",
        "finite_time_lyapunov",
        "sample_energy_shell",
    ),
    "jaxbill._analysis.indicators": (
        "FastLyapunovIndicator",
        "Megno",
        "fli",
        "fli_map",
        "megno",
    ),
    "jaxbill._analysis.lyapunov": (
        "LyapunovSpectrum",
        "lyapunov_spectrum",
    ),
    "jaxbill._analysis.periodic": (
        "find_periodic_orbit",
        "find_periodic_orbits",
    ),
    "jaxbill._analysis.periodic_orbit": (
        "STABILITY_LABELS",
        "PeriodicOrbit",
    ),
    "jaxbill._analysis.periodic_rotation": ("continue_periodic_orbit",),
    "jaxbill._analysis.section_measures": (
        "CHAOTIC_DIVERGENCE",
        "count_islands",
        "covered_fraction",
        "curve_thickness",
        "is_chaotic",
        "orbits_with_twins",
        "twin_divergence",
    ),
    "jaxbill._check.checker": (
        "CheckFlag",
        "CheckReport",
        "CheckResult",
        "check",
    ),
    "jaxbill._engine.collision": (
        "Orbit",
        "collide",
        "orbit",
        "orbit_sharded",
    ),
    "jaxbill._engine.results": ("Result",),
    "jaxbill._engine.sharding": ("orbit_mesh",),
    "jaxbill._engine.tangent": (
        "dynamical_frame",
        "dynamical_indices",
        "phase_velocity",
        "tangent_map",
    ),
    "jaxbill._explorer": ("explore",),
    "jaxbill._runs.files": ("Checkpoint",),
    "jaxbill._runs.guard": ("RunInterrupted",),
    "jaxbill._runs.streaming": (
        "Run",
        "Section",
        "SectionPoints",
        "run",
    ),
    "jaxbill._scenes.bodies.base": ("Body",),
    "jaxbill._scenes.bodies.dumbbell": ("Dumbbell",),
    "jaxbill._scenes.bodies.ellipse": ("EllipseBody",),
    "jaxbill._scenes.bodies.point": ("PointBody",),
    "jaxbill._scenes.bodies.polygon": ("PolygonBody",),
    "jaxbill._scenes.body_in_table": ("BodyInTable",),
    "jaxbill._scenes.circle.scene": ("StickInCircle",),
    "jaxbill._scenes.circle.sections": (
        "birkhoff_section",
        "incoming_states",
        "paper_section",
        "reduced_section",
        "reduced_section_bounds",
        "section_seeds",
        "section_state",
        "wall_length",
    ),
    "jaxbill._scenes.ellipse.scene": ("StickInEllipse",),
    "jaxbill._scenes.ellipse.sections": ("ellipse_length",),
    "jaxbill._scenes.protocols": (
        "angular_momentum",
        "end_points",
        "energy",
    ),
    "jaxbill._scenes.tables.base": (
        "Motion",
        "Piece",
        "Table",
    ),
    "jaxbill._scenes.tables.circle": (
        "Circle",
        "DiscWall",
    ),
    "jaxbill._scenes.tables.convex_function": (
        "ConvexTable",
        "FunctionWall",
    ),
    "jaxbill._scenes.tables.ellipse": (
        "Ellipse",
        "EllipseWall",
    ),
    "jaxbill._scenes.tables.finite": (
        "Arc",
        "Segment",
    ),
    "jaxbill._scenes.tables.flat": (
        "HalfPlane",
        "Strip",
    ),
    "jaxbill._scenes.tables.lorentz": (
        "LorentzGas",
        "PeriodicWall",
    ),
    "jaxbill._scenes.tables.mushroom": ("Mushroom",),
    "jaxbill._scenes.tables.obstacles": (
        "DiscObstacle",
        "EllipseObstacle",
        "WithObstacles",
    ),
    "jaxbill._scenes.tables.polygon": ("Polygon",),
    "jaxbill._scenes.tables.sinai": ("Sinai",),
    "jaxbill._scenes.tables.stadium": (
        "CapsuleWall",
        "Stadium",
    ),
    "jaxbill._scenes.walls.scene_2d": ("StickBetweenWalls2D",),
    "jaxbill._scenes.walls.scene_3d": ("StickBetweenWalls3D",),
    "jaxbill._scenes.walls.sections": (
        "floor_section",
        "floor_section_bound",
        "floor_seeds",
        "floor_state",
        "orbits_with_twin_distances",
        "reduced_wall_section",
        "separation_collisions",
        "theta_z_path",
        "wall_twin_divergence",
    ),
    "jaxbill.studies.arnold_web": (
        "TorusFrequencies",
        "resonances",
        "torus_frequencies",
    ),
    "jaxbill.studies.small_stick": (
        "EnsembleLyapunov",
        "ensemble_lyapunov",
    ),
}

if TYPE_CHECKING:  # the same names, for type checkers, IDEs and the API reference
    from jaxbill._analysis.chaos import (
        FiniteTimeLyapunov,
        chaos_threshold,
        chaotic_fraction,
        finite_time_lyapunov,
        sample_energy_shell,
    )
    from jaxbill._analysis.indicators import (
        FastLyapunovIndicator,
        Megno,
        fli,
        fli_map,
        megno,
    )
    from jaxbill._analysis.lyapunov import LyapunovSpectrum, lyapunov_spectrum
    from jaxbill._analysis.periodic import (
        find_periodic_orbit,
        find_periodic_orbits,
    )
    from jaxbill._analysis.periodic_orbit import STABILITY_LABELS, PeriodicOrbit
    from jaxbill._analysis.periodic_rotation import continue_periodic_orbit
    from jaxbill._analysis.section_measures import (
        CHAOTIC_DIVERGENCE,
        count_islands,
        covered_fraction,
        curve_thickness,
        is_chaotic,
        orbits_with_twins,
        twin_divergence,
    )
    from jaxbill._check.checker import (
        CheckFlag,
        CheckReport,
        CheckResult,
        check,
    )
    from jaxbill._engine.collision import (
        Orbit,
        collide,
        orbit,
        orbit_sharded,
    )
    from jaxbill._engine.results import Result
    from jaxbill._engine.sharding import orbit_mesh
    from jaxbill._engine.tangent import (
        dynamical_frame,
        dynamical_indices,
        phase_velocity,
        tangent_map,
    )
    from jaxbill._explorer import explore
    from jaxbill._runs.files import Checkpoint
    from jaxbill._runs.guard import RunInterrupted
    from jaxbill._runs.streaming import Run, Section, SectionPoints, run
    from jaxbill._scenes.bodies.base import Body
    from jaxbill._scenes.bodies.dumbbell import Dumbbell
    from jaxbill._scenes.bodies.ellipse import EllipseBody
    from jaxbill._scenes.bodies.point import PointBody
    from jaxbill._scenes.bodies.polygon import PolygonBody
    from jaxbill._scenes.body_in_table import BodyInTable
    from jaxbill._scenes.circle.scene import StickInCircle
    from jaxbill._scenes.circle.sections import (
        birkhoff_section,
        incoming_states,
        paper_section,
        reduced_section,
        reduced_section_bounds,
        section_seeds,
        section_state,
        wall_length,
    )
    from jaxbill._scenes.ellipse.scene import StickInEllipse
    from jaxbill._scenes.ellipse.sections import ellipse_length
    from jaxbill._scenes.protocols import (
        angular_momentum,
        end_points,
        energy,
    )
    from jaxbill._scenes.tables.base import Motion, Piece, Table
    from jaxbill._scenes.tables.circle import Circle, DiscWall
    from jaxbill._scenes.tables.convex_function import ConvexTable, FunctionWall
    from jaxbill._scenes.tables.ellipse import Ellipse, EllipseWall
    from jaxbill._scenes.tables.finite import Arc, Segment
    from jaxbill._scenes.tables.flat import HalfPlane, Strip
    from jaxbill._scenes.tables.lorentz import LorentzGas, PeriodicWall
    from jaxbill._scenes.tables.mushroom import Mushroom
    from jaxbill._scenes.tables.obstacles import (
        DiscObstacle,
        EllipseObstacle,
        WithObstacles,
    )
    from jaxbill._scenes.tables.polygon import Polygon
    from jaxbill._scenes.tables.sinai import Sinai
    from jaxbill._scenes.tables.stadium import CapsuleWall, Stadium
    from jaxbill._scenes.walls.scene_2d import StickBetweenWalls2D
    from jaxbill._scenes.walls.scene_3d import StickBetweenWalls3D
    from jaxbill._scenes.walls.sections import (
        floor_section,
        floor_section_bound,
        floor_seeds,
        floor_state,
        orbits_with_twin_distances,
        reduced_wall_section,
        separation_collisions,
        theta_z_path,
        wall_twin_divergence,
    )
    from jaxbill.studies.arnold_web import (
        TorusFrequencies,
        resonances,
        torus_frequencies,
    )
    from jaxbill.studies.small_stick import EnsembleLyapunov, ensemble_lyapunov

__all__ = [
    "BodyInTable",
    "PointBody",
    "Dumbbell",
    "PolygonBody",
    "EllipseBody",
    "Circle",
    "Ellipse",
    "Stadium",
    "Polygon",
    "Strip",
    "ConvexTable",
    "Sinai",
    "LorentzGas",
    "Mushroom",
    "WithObstacles",
    "DiscObstacle",
    "EllipseObstacle",
    "Segment",
    "Arc",
    "PeriodicWall",
    "Body",
    "Table",
    "Piece",
    "Motion",
    "DiscWall",
    "EllipseWall",
    "HalfPlane",
    "CapsuleWall",
    "FunctionWall",
    "StickInCircle",
    "StickInEllipse",
    "StickBetweenWalls2D",
    "StickBetweenWalls3D",
    "collide",
    "orbit",
    "Orbit",
    "Result",
    "run",
    "Run",
    "Section",
    "SectionPoints",
    "Checkpoint",
    "RunInterrupted",
    "orbit_sharded",
    "orbit_mesh",
    "backend_settings",
    "energy",
    "angular_momentum",
    "end_points",
    "paper_section",
    "reduced_section",
    "birkhoff_section",
    "reduced_section_bounds",
    "section_state",
    "section_seeds",
    "incoming_states",
    "wall_length",
    "ellipse_length",
    "floor_section",
    "floor_section_bound",
    "floor_seeds",
    "floor_state",
    "reduced_wall_section",
    "theta_z_path",
    "wall_twin_divergence",
    "orbits_with_twin_distances",
    "separation_collisions",
    "curve_thickness",
    "covered_fraction",
    "count_islands",
    "twin_divergence",
    "is_chaotic",
    "orbits_with_twins",
    "CHAOTIC_DIVERGENCE",
    "tangent_map",
    "dynamical_indices",
    "dynamical_frame",
    "phase_velocity",
    "lyapunov_spectrum",
    "LyapunovSpectrum",
    "sample_energy_shell",
    "finite_time_lyapunov",
    "FiniteTimeLyapunov",
    "chaotic_fraction",
    "chaos_threshold",
    "fli",
    "megno",
    "fli_map",
    "FastLyapunovIndicator",
    "Megno",
    "ensemble_lyapunov",
    "EnsembleLyapunov",
    "torus_frequencies",
    "TorusFrequencies",
    "resonances",
    "find_periodic_orbit",
    "find_periodic_orbits",
    "continue_periodic_orbit",
    "PeriodicOrbit",
    "STABILITY_LABELS",
    "check",
    "explore",
    "CheckResult",
    "CheckReport",
    "CheckFlag",
]
__version__ = "0.1.0"


_MODULE_OF = {name: module for module, names in _PUBLIC.items() for name in names}


def __getattr__(name: str):
    module = _MODULE_OF.get(name)
    if module is not None:
        value = getattr(importlib.import_module(module), name)
        globals()[name] = value  # found directly from now on
        return value
    if not name.startswith("_"):  # a public subpackage or module: jb.plotting, jb.studies
        try:
            return importlib.import_module(f"{__name__}.{name}")
        except ModuleNotFoundError as missing:
            if missing.name != f"{__name__}.{name}":
                raise
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
