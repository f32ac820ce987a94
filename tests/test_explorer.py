"""The section explorer (``jb.explore``), driven by synthetic mouse and slider events under Agg.

Every callback the figure wires up is reached the way a person reaches it:
a ``button_press_event`` at the pixel of a section point, a press on a
slider's track, a press and release on a button. The explorer runs small
surveys here (8 orbits, a few hundred collisions) to keep compile and run
times short; the defaults are exercised by the ``jaxbill explore --save`` test.
"""

from __future__ import annotations

import os
import subprocess
import sys

import matplotlib

matplotlib.use("Agg")

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from matplotlib.backend_bases import MouseButton, MouseEvent

import jaxbill as jb
from jaxbill import _explorer
from jaxbill._scenes.circle.sections import CIRCLE_CHART
from jaxbill._scenes.walls.charts import WALLS_2D_CHART

SMALL = dict(survey_orbits=8, survey_collisions=200, click_collisions=400, chunk=100)

SCENES = {
    "rotor": lambda: jb.StickInCircle(R=2.0, ell=1.2),
    "lens": lambda: jb.StickInCircle(R=2.0, ell=1.5, inertia=float("inf")),
    "circle": lambda: jb.StickInCircle(R=2.0, ell=0.0),
    "walls2d": lambda: jb.StickBetweenWalls2D(h=3.0, ell=1.0),
    "walls3d": lambda: jb.StickBetweenWalls3D(h=3.0, ell=1.0),
    "ellipse": lambda: jb.StickInEllipse(a=2.0, b=1.3, ell=0.5),
}


def _press(explorer, ax, x, y, name="button_press_event"):
    """Send a left-button mouse event at data point ``(x, y)`` of ``ax``; return it."""
    px, py = ax.transData.transform((x, y))
    event = MouseEvent(name, explorer.figure.canvas, px, py, button=MouseButton.LEFT)
    explorer.figure.canvas.callbacks.process(name, event)
    return event


def _press_button(explorer, button):
    """Press and release the mouse in the middle of a widget ``Button``."""
    for name in ("button_press_event", "button_release_event"):
        px, py = button.ax.transAxes.transform((0.5, 0.5))
        event = MouseEvent(name, explorer.figure.canvas, px, py, button=MouseButton.LEFT)
        explorer.figure.canvas.callbacks.process(name, event)


def _inside_point(explorer, fx=0.3, fy=0.2):
    """A reachable section point: ``fx`` across the panel, ``fy`` of the half-height above the middle."""
    low, high = explorer.chart.x_range(explorer.scene)
    across = np.linspace(low, high, 401)[1:-1]
    edge = explorer.chart.edge(explorer.scene, across, explorer.invariants)
    reachable = across[np.all(np.isfinite(edge), axis=-1)]
    x = reachable[0] + fx * (reachable[-1] - reachable[0])
    bottom, top = explorer.chart.edge(explorer.scene, np.array([x]), explorer.invariants)[0]
    return float(x), float(0.5 * (bottom + top) + 0.5 * fy * (top - bottom))


@pytest.fixture(scope="module", params=list(SCENES))
def explorer(request):
    opened = jb.explore(SCENES[request.param](), **SMALL)
    yield opened
    opened.close()


def test_a_click_starts_an_orbit_at_that_section_point(explorer):
    """The click's first section point is the clicked point to 1e-12, and the orbit is the scene's own."""
    x, y = _inside_point(explorer)
    event = _press(explorer, explorer.section_axes, x, y)
    assert len(explorer.orbits) >= 1, explorer.status
    clicked = explorer.orbits[-1]
    assert abs(event.xdata - x) < 1e-9 and abs(event.ydata - y) < 1e-9
    np.testing.assert_allclose(clicked.start, [event.xdata, event.ydata], rtol=0, atol=0)
    np.testing.assert_allclose(clicked.points[0], [event.xdata, event.ydata], rtol=0, atol=1e-12)
    assert clicked.collisions == SMALL["click_collisions"]
    assert clicked.points.shape == (SMALL["click_collisions"] + 1, 2)
    # The orbit is jb.orbit's from the chart's start state: its first section points agree within the
    # chaos horizon (the explorer runs it in a batch, which may round differently in the last bit).
    states, contacts = explorer.chart.start(
        explorer.scene, jnp.float64(event.xdata), jnp.float64(event.ydata), explorer.invariants
    )
    np.testing.assert_array_equal(clicked.state0, np.asarray(states))
    orb = jb.orbit(explorer.scene, states, 10)
    expected = np.asarray(explorer.chart.points(explorer.scene, orb.state, orb.contact))
    np.testing.assert_allclose(clicked.points[1:11], expected, rtol=0, atol=1e-9)
    on_section = np.all(np.isfinite(clicked.points), axis=-1)
    assert on_section.sum() > 10
    line = explorer._orbit_lines[-1][0]
    np.testing.assert_array_equal(np.asarray(line.get_xdata()), clicked.points[:, 0])


def test_a_click_outside_the_section_or_the_panel_starts_nothing(explorer):
    before = len(explorer.orbits)
    low, high = explorer.chart.x_range(explorer.scene)
    top = explorer.section_axes.get_ylim()[1]
    assert explorer.click(0.5 * (low + high), 10.0 * top) is None
    assert "not reachable" in explorer.status
    _press(explorer, explorer.configuration_axes, 0.0, 0.0)
    assert len(explorer.orbits) == before


def test_clear_button_removes_the_clicked_orbits(explorer):
    explorer.click(*_inside_point(explorer, 0.6, -0.3))
    lines_before = len(explorer.section_axes.lines)
    count = len(explorer.orbits)
    assert count >= 1
    _press_button(explorer, explorer.clear_button)
    assert explorer.orbits == []
    assert len(explorer.section_axes.lines) == lines_before - 2 * count


def test_save_button_writes_a_png(explorer, tmp_path):
    explorer.click(*_inside_point(explorer))
    explorer.save_path = tmp_path / "explorer.png"
    _press_button(explorer, explorer.save_button)
    data = explorer.save_path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    image = matplotlib.image.imread(explorer.save_path)
    assert image.shape[0] > 500 and image.shape[1] > 1000
    # not a blank page: the section's points are drawn
    assert np.std(image[..., :3]) > 0.05


@pytest.fixture(scope="module")
def rotor_explorer():
    opened = jb.explore(jb.StickInCircle(R=2.0, ell=1.2), **SMALL)
    yield opened
    opened.close()


def test_sliders_come_from_the_scene_parameters(rotor_explorer):
    # R sets the unit of length and mass the unit of mass; ell and inertia move.
    assert list(rotor_explorer.sliders) == ["ell", "inertia"]
    ell = rotor_explorer.sliders["ell"]
    assert 10.0**ell.valmax < 2.0 <= 10.0 ** (ell.valmax + 0.05)  # cut where the constructor refuses ell >= R
    lens = jb.StickInCircle(R=2.0, ell=1.5, inertia=float("inf"))
    assert [r.name for r in _explorer.slider_ranges(lens)] == ["ell"]
    walls = jb.StickBetweenWalls3D(h=3.0, ell=1.0)
    assert [r.name for r in _explorer.slider_ranges(walls)] == ["ell", "inertia"]


def test_a_slider_press_rebuilds_the_scene_and_its_survey(rotor_explorer):
    explorer = rotor_explorer
    explorer.click(*_inside_point(explorer, 0.25, 0.1))
    clicked_start = explorer.orbits[-1].start
    old_survey = explorer.survey_points.copy()
    slider = explorer.sliders["ell"]
    fraction = 0.8
    _press(explorer, slider.ax, slider.valmin + fraction * (slider.valmax - slider.valmin), 0.5)
    release = MouseEvent("button_release_event", explorer.figure.canvas, 0, 0, button=MouseButton.LEFT)
    explorer.figure.canvas.callbacks.process("button_release_event", release)
    new_ell = 10.0**slider.val
    assert abs(new_ell - 1.2) > 0.01
    assert float(explorer.scene.ell) == pytest.approx(new_ell, rel=1e-12)
    assert float(explorer.scene.R) == 2.0 and float(explorer.scene.inertia) == pytest.approx(1.44)
    assert f"ell = {new_ell:.4g}" in explorer.section_axes.get_title()
    # The survey is the new scene's: seeds spread over its section, then its orbits.
    seeds = jb.section_seeds(explorer.scene, SMALL["survey_orbits"], 0.5, 0.0)
    np.testing.assert_allclose(
        explorer.survey_points[:, 0], np.asarray(jb.reduced_section(explorer.scene, seeds)), rtol=0, atol=1e-12
    )
    orb = jb.orbit(explorer.scene, seeds, 5)
    np.testing.assert_allclose(
        explorer.survey_points[:, 1:6], np.asarray(jb.reduced_section(explorer.scene, orb.state)), rtol=0, atol=1e-9
    )
    assert not np.allclose(explorer.survey_points, old_survey, equal_nan=True)
    # The clicked orbit was rerun from the same section point in the new scene.
    assert len(explorer.orbits) == 1
    np.testing.assert_array_equal(explorer.orbits[0].start, clicked_start)
    np.testing.assert_allclose(explorer.orbits[0].points[0], clicked_start, rtol=0, atol=1e-12)


def test_set_parameter_moves_the_inertia_and_refuses_unknown_names(rotor_explorer):
    rotor_explorer.set_parameter("inertia", 0.5)
    assert float(rotor_explorer.scene.inertia) == pytest.approx(0.5, rel=1e-12)
    with pytest.raises(ValueError, match="name"):
        rotor_explorer.set_parameter("R", 3.0)


def test_a_click_compiles_nothing_and_runs_its_collisions(explorer):
    """Once the explorer is open a click compiles no program: its orbit runs in the batch program the
    survey compiled, chunk by chunk, and its start and drawing reuse what opening the explorer compiled.
    (How long a click takes is a benchmark row: ``benchmarks/bench_explorer.py``.)"""
    compiled = []

    def listener(event, duration, **kwargs):
        if event.endswith("backend_compile_duration"):
            compiled.append(kwargs.get("fun_name", event))

    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        clicked = explorer.click(*_inside_point(explorer, 0.6, -0.2))
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)
    assert clicked is not None
    assert clicked.collisions == explorer.click_collisions
    assert clicked.points.shape == (explorer.click_collisions + 1, 2)
    assert compiled == [], f"a click compiled {compiled}"


def test_explore_refuses_what_it_cannot_show():
    with pytest.raises(TypeError, match="scene"):
        jb.explore(object())
    with pytest.raises(ValueError, match="one scene, not a batch"):
        jb.explore(jb.StickInCircle(R=2.0, ell=jnp.array([1.0, 1.5])))
    with pytest.raises(ValueError, match="spin"):
        jb.explore(jb.StickBetweenWalls2D(h=3.0, ell=1.0), spin=0.3)
    with pytest.raises(ValueError, match="click_collisions"):
        jb.explore(jb.StickInCircle(R=2.0, ell=1.2), click_collisions=0)


def test_a_scene_can_bring_its_own_chart():
    """``section_chart`` asks the scene first, then the table by class (subclasses included)."""

    class Tagged(jb.StickBetweenWalls2D):
        pass

    scene = Tagged(h=3.0, ell=1.0)
    assert _explorer.section_chart(scene) is WALLS_2D_CHART
    own = CIRCLE_CHART

    class WithChart:
        section_chart = own

    assert _explorer.section_chart(WithChart()) is own


def test_jaxbill_explore_save_writes_a_screenshot(tmp_path):
    target = tmp_path / "explorer.png"
    env = dict(os.environ, JAX_PLATFORMS="cpu")
    proc = subprocess.run(
        [sys.executable, "-m", "jaxbill.cli", "explore", "--save", str(target), "--clicks", "2"],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert target.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert proc.stdout.count("4000 collisions") == 2, proc.stdout
    assert "2 clicked orbits" in proc.stdout


def test_jaxbill_explore_opens_the_ellipse(tmp_path):
    target = tmp_path / "ellipse.png"
    env = dict(os.environ, JAX_PLATFORMS="cpu")
    command = ["explore", "--scene", "ellipse", "--a", "2", "--b", "1.3", "--ell", "0.6", "--clicks", "1"]
    proc = subprocess.run(
        [sys.executable, "-m", "jaxbill.cli", *command, "--save", str(target)],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert target.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "Birkhoff section of the touching end of StickInEllipse with 1 clicked orbits" in proc.stdout, proc.stdout


def test_jaxbill_explore_bad_ell_exits_2_naming_it(tmp_path):
    env = dict(os.environ, JAX_PLATFORMS="cpu")
    proc = subprocess.run(
        [sys.executable, "-m", "jaxbill.cli", "explore", "--ell", "2.5", "--save", str(tmp_path / "x.png")],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert proc.returncode == 2
    assert "ell" in proc.stderr and "Traceback" not in proc.stderr
