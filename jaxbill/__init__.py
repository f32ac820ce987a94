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
"""

import jax

from jaxbill._engine.backend import backend_settings, configure

configure()
jax.config.update("jax_enable_x64", True)

from jaxbill._analysis.chaos import (  # noqa: E402
    FiniteTimeLyapunov,
    chaos_threshold,
    chaotic_fraction,
    finite_time_lyapunov,
    sample_energy_shell,
)
from jaxbill._analysis.indicators import FastLyapunovIndicator, Megno, fli, fli_map, megno  # noqa: E402
from jaxbill._analysis.lyapunov import LyapunovSpectrum, lyapunov_spectrum  # noqa: E402
from jaxbill._analysis.periodic import find_periodic_orbit, find_periodic_orbits  # noqa: E402
from jaxbill._analysis.periodic_orbit import STABILITY_LABELS, PeriodicOrbit  # noqa: E402
from jaxbill._analysis.periodic_rotation import continue_periodic_orbit  # noqa: E402
from jaxbill._analysis.section_measures import (  # noqa: E402
    CHAOTIC_DIVERGENCE,
    count_islands,
    covered_fraction,
    curve_thickness,
    is_chaotic,
    orbits_with_twins,
    twin_divergence,
)
from jaxbill._check.checker import CheckFlag, CheckReport, CheckResult, check  # noqa: E402
from jaxbill._engine.collision import (  # noqa: E402
    Orbit,
    collide,
    orbit,
    orbit_sharded,
)
from jaxbill._engine.results import Result  # noqa: E402
from jaxbill._engine.sharding import orbit_mesh  # noqa: E402
from jaxbill._engine.tangent import dynamical_frame, dynamical_indices, phase_velocity, tangent_map  # noqa: E402
from jaxbill._explorer import explore  # noqa: E402
from jaxbill._runs.files import Checkpoint  # noqa: E402
from jaxbill._runs.guard import RunInterrupted  # noqa: E402
from jaxbill._runs.streaming import Run, Section, SectionPoints, run  # noqa: E402
from jaxbill._scenes.bodies.base import Body  # noqa: E402
from jaxbill._scenes.bodies.dumbbell import Dumbbell  # noqa: E402
from jaxbill._scenes.bodies.ellipse import EllipseBody  # noqa: E402
from jaxbill._scenes.bodies.point import PointBody  # noqa: E402
from jaxbill._scenes.bodies.polygon import PolygonBody  # noqa: E402
from jaxbill._scenes.body_in_table import BodyInTable  # noqa: E402
from jaxbill._scenes.circle.scene import StickInCircle  # noqa: E402
from jaxbill._scenes.circle.sections import (  # noqa: E402
    birkhoff_section,
    incoming_states,
    paper_section,
    reduced_section,
    reduced_section_bounds,
    section_seeds,
    section_state,
    wall_length,
)
from jaxbill._scenes.ellipse.scene import StickInEllipse  # noqa: E402
from jaxbill._scenes.ellipse.sections import ellipse_length  # noqa: E402
from jaxbill._scenes.protocols import angular_momentum, end_points, energy  # noqa: E402
from jaxbill._scenes.tables.base import Motion, Piece, Table  # noqa: E402
from jaxbill._scenes.tables.circle import Circle, DiscWall  # noqa: E402
from jaxbill._scenes.tables.convex_function import ConvexTable, FunctionWall  # noqa: E402
from jaxbill._scenes.tables.ellipse import Ellipse, EllipseWall  # noqa: E402
from jaxbill._scenes.tables.finite import Arc, Segment  # noqa: E402
from jaxbill._scenes.tables.flat import HalfPlane, Strip  # noqa: E402
from jaxbill._scenes.tables.lorentz import LorentzGas, PeriodicWall  # noqa: E402
from jaxbill._scenes.tables.mushroom import Mushroom  # noqa: E402
from jaxbill._scenes.tables.obstacles import DiscObstacle, EllipseObstacle, WithObstacles  # noqa: E402
from jaxbill._scenes.tables.polygon import Polygon  # noqa: E402
from jaxbill._scenes.tables.sinai import Sinai  # noqa: E402
from jaxbill._scenes.tables.stadium import CapsuleWall, Stadium  # noqa: E402
from jaxbill._scenes.walls.scene_2d import StickBetweenWalls2D  # noqa: E402
from jaxbill._scenes.walls.scene_3d import StickBetweenWalls3D  # noqa: E402
from jaxbill._scenes.walls.sections import (  # noqa: E402
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
from jaxbill.studies.arnold_web import TorusFrequencies, resonances, torus_frequencies  # noqa: E402
from jaxbill.studies.small_stick import EnsembleLyapunov, ensemble_lyapunov  # noqa: E402

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
