"""jaxbill: rigid-body billiards in JAX.

Importing jaxbill switches JAX to float64 (``jax_enable_x64``): every collision
time and state is computed in double precision, and the library's accuracy
claims hold only there.
"""

import jax

jax.config.update("jax_enable_x64", True)

from ._checker import check, CheckFlag, CheckReport, CheckResult  # noqa: E402
from ._collision import collide, orbit, Orbit  # noqa: E402
from ._section_measures import count_islands, covered_fraction, curve_thickness, is_chaotic, twin_divergence  # noqa: E402
from ._sections import (  # noqa: E402
    birkhoff_section,
    incoming_states,
    paper_section,
    reduced_section,
    reduced_section_bounds,
    section_seeds,
    section_state,
    wall_length,
)
from ._stick_in_circle import StickInCircle, energy, angular_momentum, end_points  # noqa: E402

__all__ = [
    "StickInCircle",
    "collide",
    "orbit",
    "Orbit",
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
    "curve_thickness",
    "covered_fraction",
    "count_islands",
    "twin_divergence",
    "is_chaotic",
    "check",
    "CheckResult",
    "CheckReport",
    "CheckFlag",
]
__version__ = "0.1.0"
