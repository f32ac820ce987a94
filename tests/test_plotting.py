"""Pictures: section axes labelled by the scene the points come from, and section points visible as drawn."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

import jaxbill as jb
from jaxbill import plotting


def _labels(ax):
    return ax.get_xlabel(), ax.get_ylabel()


def test_an_ellipse_section_is_labelled_with_the_ellipse_s_coordinates():
    """The ellipse's ``"birkhoff"`` p is sqrt(M) v_t / sqrt(2E) (spin energy included), not the circle's sin chi."""
    ellipse = jb.StickInEllipse(a=2.0, b=1.3, ell=0.6)
    state0 = np.array([0.1, 0.2, 0.3, 0.7, -0.4, 0.9])
    points = np.asarray(ellipse.section(jb.orbit(ellipse, state0, 50).state, name="birkhoff"))
    ax = plotting.draw_section(Figure().add_subplot(), points, "birkhoff", scene=ellipse)
    xlabel, ylabel = _labels(ax)
    assert "(a, 0)" in xlabel and r"\sqrt{2E}" in ylabel and "chi" not in ylabel
    circle_x, circle_y = _labels(plotting.draw_section(Figure().add_subplot(), points, "birkhoff"))
    assert (circle_x, circle_y) != (xlabel, ylabel) and "chi" in circle_y
    # every section the ellipse offers has labels, and one it lacks is refused by name
    for name in ellipse.sections:
        plotting.draw_section(Figure().add_subplot(), points, name, scene=ellipse)
    with pytest.raises(ValueError, match="kind must be one of"):
        plotting.draw_section(Figure().add_subplot(), points, "paper", scene=ellipse)


def test_a_circle_section_has_the_same_labels_with_or_without_its_scene():
    scene = jb.StickInCircle(R=2.0, ell=1.9)
    points = np.zeros((10, 2))
    for kind in scene.sections:
        with_scene = _labels(plotting.draw_section(Figure().add_subplot(), points, kind, scene=scene))
        assert with_scene == _labels(plotting.draw_section(Figure().add_subplot(), points, kind))


def test_section_points_at_the_default_size_show_as_dark_dots():
    """Each of 100 well-separated black points darkens at least one pixel to below half grey at 100 dpi."""
    fig = Figure(figsize=(4, 4), dpi=100)
    ax = fig.add_axes((0, 0, 1, 1))
    ax.set_axis_off()
    grid = (np.arange(10) + 0.5) / 10
    points = np.stack(np.meshgrid(grid, grid), axis=-1).reshape(-1, 2)
    plotting.draw_section(ax, points, "reduced", colors="k")
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    grey = np.asarray(canvas.buffer_rgba())[..., :3].mean(axis=-1) / 255  # (400, 400), 1 = white
    cells = grey.reshape(10, 40, 10, 40).min(axis=(1, 3))  # the darkest pixel of each point's 40 x 40 cell
    assert np.all(cells < 0.5), f"{np.sum(cells >= 0.5)} of 100 points fainter than half grey"
