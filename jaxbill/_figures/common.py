"""What every group of figures shares: the run sizes, the start energy, the twins' velocity turn, and a
panel's common value."""

from __future__ import annotations

import dataclasses
import time

import numpy as np

ENERGY = 0.5
TWIN_DELTA = 1e-11  # twin_states' default: the velocity turn of each orbit's twin


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


def common_value(values):
    """The value every entry shares (to 1e-12), rounded; the list of values where they differ."""
    values = np.asarray(values, dtype=np.float64)
    if np.allclose(values, values.flat[0], rtol=1e-12, atol=1e-12):
        return round(float(values.flat[0]), 12)
    return values.tolist()


def figure_record(name: str, file: str, description: str, panels: list, started: float) -> dict:
    """One figure's entry in the summary: its name, PNG, description, panels and seconds since ``started``."""
    return {
        "name": name,
        "file": file,
        "description": description,
        "panels": panels,
        "seconds": time.perf_counter() - started,
    }
