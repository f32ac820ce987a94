"""An interactive explorer of a scene's area-preserving Poincaré section, on matplotlib.

``explore(scene)`` opens one figure:

* the **section panel**: the scene's section at fixed invariants (for
  instance ``StickInCircle``: the reduced section ``(s, p)`` at ``E`` and
  ``L``; ``StickInEllipse``: the Birkhoff section of the touching end at
  ``E``; the wall scenes: the floor section ``(theta, p)`` at ``E'`` and, in
  3D, ``I w_z``), seeded with a survey of orbits that start evenly spread
  over it and run as one vmapped batch;
* the **configuration panel**: the last clicked orbit's first collisions
  with the stick drawn at its contacts;
* **sliders** for the scene's own parameters (every finite parameter except
  the first, which sets the unit of length, and ``mass``, which sets the unit
  of mass) and **buttons** to clear the clicked orbits and to save a PNG.

A left click in the section panel starts an orbit at the state just after a
collision at that section point (``section_state`` / ``floor_state``, at the
panel's invariants) and draws its section points chunk by chunk as they are
computed. Moving a slider rebuilds the scene, reruns the survey and reruns
every clicked orbit from its section point, in one batch.

What the explorer needs from a scene is a ``SectionChart``: how to map states
to section points and back, how to seed the section, where its edge is and
how to draw the configuration. ``section_chart(scene)`` asks the scene first
(a ``section_chart`` attribute) and otherwise looks the scene's class up in
``SECTION_CHARTS``; ``register_section_chart`` adds a class. Nothing here
branches on the kind of scene, so a new scene joins by providing a chart.

Backends: in Jupyter run ``%matplotlib widget`` (ipympl) before ``explore``;
on a desktop ``matplotlib.pyplot.show()`` opens an ordinary window. Under
``Agg`` (no display) every callback still runs: the tests drive it with
synthetic mouse and slider events, and ``jaxbill explore --save`` uses it.
"""

from __future__ import annotations

import dataclasses
import math
import pathlib
import time
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbill._engine.collision import Orbit, orbit
from jaxbill._scenes.protocols import HasSection, SectionChart

# A user's scene class may be registered here; jaxbill's scenes carry their own
# ``section_chart`` (``jaxbill._scenes.protocols.HasSection``).


SECTION_CHARTS: dict[type, SectionChart] = {}


def register_section_chart(scene_class: type, chart: SectionChart) -> None:
    """Let ``explore`` open scenes of ``scene_class`` (a scene may instead carry a ``section_chart`` attribute)."""
    SECTION_CHARTS[scene_class] = chart


def section_chart(scene) -> SectionChart:
    """The ``SectionChart`` of ``scene``: its own ``section_chart`` attribute, else ``SECTION_CHARTS[type(scene)]``.

    Raises:
        TypeError: for a scene with neither (it has no section to explore).
    """
    own = getattr(scene, "section_chart", None)
    if own is not None:
        return own
    for scene_class in type(scene).__mro__:
        if scene_class in SECTION_CHARTS:
            return SECTION_CHARTS[scene_class]
    known = ", ".join(sorted(c.__name__ for c in SECTION_CHARTS)) or "none registered"
    raise TypeError(
        f"scene: {type(scene).__name__} has no area-preserving section to explore "
        f"(known: {known}; give the scene a section_chart or call register_section_chart)"
    )


# -- the scene's parameters as sliders ---------------------------------------------

# The span of each slider, as factors of the parameter's starting value (log scale);
# ranges are then cut to the values the scene's own constructor accepts.
DEFAULT_SPAN = (0.1, 10.0)
SLIDER_SPANS = {"inertia": (1e-3, 10.0)}
# Parameters that set the units: the first one (the unit of length) and the mass.
UNIT_PARAMETERS = ("mass",)


def scene_parameters(scene) -> dict[str, float]:
    """The scene's parameters as floats, by name: the scene's own ``parameters`` where it has them (a body in a
    table: those of its constructor, or of its table and body), else its non-static dataclass fields (all must
    be scalars)."""
    own = getattr(scene, "parameters", None)
    if own is not None:
        return dict(own)
    values = {}
    for field in dataclasses.fields(scene):
        if field.metadata.get("static", False):
            continue
        value = np.asarray(getattr(scene, field.name))
        if value.ndim != 0:
            raise ValueError(f"scene: explore needs one scene, not a batch ({field.name} has shape {value.shape})")
        values[field.name] = float(value)
    return values


def rebuild(scene, **changes):
    """A new scene of the same class with some parameters changed; ValueError if its constructor refuses them.

    Also refuses a change of the scene's static ``kind`` (e.g. a rotor
    becoming a circle at ``ell = 0``), which would change the section.
    """
    parameters = scene_parameters(scene)
    unknown = set(changes) - set(parameters)
    if unknown:
        raise ValueError(
            f"{sorted(unknown)[0]}: not a parameter of {type(scene).__name__} (its parameters: {', '.join(parameters)})"
        )
    parameters.update({name: float(value) for name, value in changes.items()})
    replaced = getattr(scene, "with_parameters", None)
    new = replaced(**parameters) if replaced is not None else type(scene)(**parameters)
    if getattr(new, "kind", None) != getattr(scene, "kind", None):
        raise ValueError(f"{', '.join(changes)}: these values make a {new.kind!r} scene, not {scene.kind!r}")
    return new


class SliderRange(NamedTuple):
    """A slider over ``log10`` of one parameter: ``name``, ``low``, ``high`` (``log10`` of the values)."""

    name: str
    low: float
    high: float


def slider_ranges(scene) -> list[SliderRange]:
    """One log-scale slider per parameter the explorer may move, with the range the scene accepts.

    The first parameter (the unit of length: ``R``, ``h``) and
    ``UNIT_PARAMETERS`` stay fixed, as do infinite ones (the static lens's
    inertia). The span is ``SLIDER_SPANS.get(name, DEFAULT_SPAN)`` times the
    starting value, cut to the run of values around it that ``rebuild``
    accepts (tried on a grid of 49 values).
    """
    parameters = scene_parameters(scene)
    ranges = []
    for name, value in list(parameters.items())[1:]:
        if name in UNIT_PARAMETERS or not (math.isfinite(value) and value > 0.0):
            continue
        low, high = SLIDER_SPANS.get(name, DEFAULT_SPAN)
        grid = np.linspace(math.log10(value * low), math.log10(value * high), 49)
        accepted = np.array([_accepts(scene, name, 10.0**g) for g in grid])
        here = int(np.argmin(np.abs(grid - math.log10(value))))
        first, last = here, here
        while first > 0 and accepted[first - 1]:
            first -= 1
        while last < len(grid) - 1 and accepted[last + 1]:
            last += 1
        ranges.append(
            SliderRange(name, float(min(grid[first], math.log10(value))), float(max(grid[last], math.log10(value))))
        )
    return ranges


def _accepts(scene, name: str, value: float) -> bool:
    try:
        rebuild(scene, **{name: value})
    except ValueError:
        return False
    return True


# -- the explorer ----------------------------------------------------------------------


class ClickedOrbit(NamedTuple):
    """An orbit started from the section panel.

    Attributes:
        start: ``(2,)`` the section point it starts from (where the click was).
        state0: ``(S,)`` the state just after a collision there.
        points: ``(m, 2)`` its section points, the start first, then one per
            collision on the section (NaN rows for collisions off it).
        collisions: how many collisions were computed.
    """

    start: np.ndarray
    state0: np.ndarray
    points: np.ndarray
    collisions: int


# A window redraws the whole figure (tens of milliseconds with the survey): while a click's
# orbit is computed, draw its points at most this often.
REDRAW_SECONDS = 0.25

# Colours of clicked orbits, in turn: strong against the pale survey.
CLICK_COLORS = ("#d62728", "#111111", "#ff7f0e", "#c71585", "#8b4513", "#e6194b")


class Explorer:
    """The figure, widgets and callbacks of ``explore`` (see the module docstring).

    Attributes:
        scene: the scene shown now (a slider move replaces it).
        chart: its ``SectionChart``.
        invariants: the section's fixed quantities, e.g. ``{"energy": 0.5,
            "angular_momentum": 0.0}``.
        figure: the matplotlib ``Figure``.
        section_axes, configuration_axes: the two panels.
        sliders: ``{parameter name: matplotlib.widgets.Slider}`` (over ``log10``
            of the value).
        clear_button, save_button: ``matplotlib.widgets.Button``.
        survey_points: ``(B, n + 1, 2)`` the survey's section points.
        survey_message: what the survey was and how long it took.
        orbits: the clicked orbits, a list of ``ClickedOrbit``.
        save_path: where the save button writes its PNG.
        status: the last message in the status line.
    """

    def __init__(
        self,
        scene,
        invariants: dict[str, float] | None = None,
        *,
        survey_orbits: int = 24,
        survey_collisions: int = 1000,
        click_collisions: int = 4000,
        chunk: int = 500,
        configuration_collisions: int = 24,
        save_path="jaxbill_explorer.png",
    ):
        import matplotlib.pyplot as plt
        from matplotlib.widgets import Button, Slider

        self.chart = section_chart(scene)
        given = dict(invariants or {})
        unknown = set(given) - set(self.chart.invariant_symbols)
        if unknown:
            raise ValueError(
                f"{sorted(unknown)[0]}: not an invariant of the {self.chart.title} "
                f"(it takes {', '.join(self.chart.invariant_symbols)})"
            )
        for name, value in [
            ("survey_orbits", survey_orbits),
            ("survey_collisions", survey_collisions),
            ("click_collisions", click_collisions),
            ("chunk", chunk),
            ("configuration_collisions", configuration_collisions),
        ]:
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} must be an integer >= 1; got {value!r}")
        scene_parameters(scene)  # a batch of scenes is refused here, naming the parameter
        self._given_invariants = given
        self.scene = scene
        self.invariants = {**self.chart.default_invariants(scene), **given}
        self.survey_orbits, self.survey_collisions = survey_orbits, survey_collisions
        self.click_collisions, self.chunk = click_collisions, min(chunk, click_collisions)
        self.configuration_collisions = configuration_collisions
        self.save_path = pathlib.Path(save_path)
        self.orbits: list[ClickedOrbit] = []
        self._orbit_lines = []
        self._survey_lines = []
        self._edge_lines = []
        self._section_points = eqx.filter_jit(self.chart.points)
        # One chunk of a batch, compiled whole: jb.orbit's eager checks and its split over
        # devices cost more than the chunk itself. Starts come from the chart (valid, or NaN
        # and left out); under jit an invalid lane would be NaN, which ends its drawing.
        self._run_chunk = eqx.filter_jit(lambda scene, states: orbit(scene, states, self.chunk))

        self.figure = plt.figure(figsize=(13.0, 7.2))
        figure = self.figure
        self.section_axes = figure.add_axes((0.06, 0.30, 0.52, 0.62))
        self.configuration_axes = figure.add_axes((0.64, 0.30, 0.33, 0.62))
        ranges = slider_ranges(scene)
        self.sliders = {}
        for row, (name, low, high) in enumerate(ranges):
            slider_axes = figure.add_axes((0.14, 0.17 - 0.045 * row, 0.40, 0.03))
            slider = Slider(slider_axes, name, low, high, valinit=math.log10(scene_parameters(scene)[name]))
            slider.valtext.set_text(f"{10.0**slider.val:.4g}")
            slider.on_changed(self._slider_moved(name))
            self.sliders[name] = slider
        self.clear_button = Button(figure.add_axes((0.66, 0.14, 0.12, 0.05)), "clear orbits")
        self.save_button = Button(figure.add_axes((0.80, 0.14, 0.12, 0.05)), "save PNG")
        self.clear_button.on_clicked(lambda event: self.clear())
        self.save_button.on_clicked(lambda event: self.save())
        self._status_text = figure.text(0.06, 0.025, "", fontsize=9, color="0.25")
        self.status = ""
        self._click_connection = figure.canvas.mpl_connect("button_press_event", self._on_press)

        self._draw_scene_and_survey()
        # The survey compiled the one batch program that clicks use too; compile the rest of a click now
        # (its start, its first section point, the configuration panel), showing the first survey orbit.
        first = self.survey_points[0, 0]
        states, contacts = self.chart.start(self.scene, jnp.float64(first[0]), jnp.float64(first[1]), self.invariants)
        self._section_points(self.scene, np.asarray(states)[None], np.asarray(contacts)[None])
        self._show_survey_orbit()
        self._say(
            f"click in the section to start an orbit there ({self.click_collisions} collisions); {self.survey_message}"
        )

    # -- what the callbacks do (callable directly too) --

    def click(self, x: float, y: float) -> ClickedOrbit | None:
        """Start an orbit at section point ``(x, y)`` and draw it; ``None`` if the point is not reachable.

        Runs ``click_collisions`` collisions in chunks of ``chunk``; the section
        points computed so far are drawn after a chunk whenever
        ``REDRAW_SECONDS`` have passed since the last drawing, and at the end.
        """
        started = time.perf_counter()
        states, contacts = self.chart.start(self.scene, jnp.float64(x), jnp.float64(y), self.invariants)
        state0, contact0 = np.asarray(states), np.asarray(contacts)
        if not np.all(np.isfinite(state0)):
            self._say(f"({x:.4g}, {y:.4g}) is not reachable at {self._invariants_text()}: click inside the outline")
            return None
        color = CLICK_COLORS[len(self.orbits) % len(CLICK_COLORS)]
        first = np.asarray(self._section_points(self.scene, state0[None], contact0[None]))
        (line,) = self.section_axes.plot(
            first[:, 0],
            first[:, 1],
            linestyle="none",
            marker=".",
            markersize=1.8,
            markeredgewidth=0,
            color=color,
            zorder=3,
        )
        (marker,) = self.section_axes.plot([x], [y], marker="+", markersize=9, mew=1.6, color=color, zorder=4)
        pieces, done, drawn = [first], 0, started
        for orb, points in self._orbit_chunks(state0[None], self.click_collisions):
            pieces.append(points[0])
            line.set_data(*np.concatenate(pieces).T)
            if done == 0:
                self._draw_configuration(state0, jax.tree.map(lambda leaf: leaf[0], orb), color)
            done += len(points[0])
            if time.perf_counter() - drawn > REDRAW_SECONDS:
                self._say(f"orbit {len(self.orbits) + 1} from ({x:.4g}, {y:.4g}): {done} collisions so far")
                self._redraw()
                drawn = time.perf_counter()
        clicked = ClickedOrbit(np.array([x, y], dtype=np.float64), state0, np.concatenate(pieces), done)
        self.orbits.append(clicked)
        self._orbit_lines.append((line, marker))
        self._say(
            f"orbit {len(self.orbits)} from ({x:.4g}, {y:.4g}): {done} collisions in "
            f"{time.perf_counter() - started:.2f} s"
        )
        self._redraw()
        return clicked

    def set_parameter(self, name: str, value: float) -> None:
        """Move the slider of parameter ``name`` to ``value`` (which rebuilds the scene, as a drag would)."""
        if name not in self.sliders:
            raise ValueError(f"name: no slider for {name!r} (sliders: {', '.join(self.sliders) or 'none'})")
        self.sliders[name].set_val(math.log10(value))

    def clear(self) -> None:
        """Remove the clicked orbits (the survey stays)."""
        for line, marker in self._orbit_lines:
            line.remove()
            marker.remove()
        self._orbit_lines, self.orbits = [], []
        self._show_survey_orbit()
        self._say("cleared the clicked orbits")
        self._redraw()

    def save(self, path=None, *, dpi: float = 110) -> pathlib.Path:
        """Write the figure as a PNG to ``path`` (default ``save_path``) at ``dpi``; return the path."""
        target = pathlib.Path(self.save_path if path is None else path)
        self.figure.savefig(target, dpi=dpi)  # with the status line as it was: the picture of what was done
        self._say(f"saved {target}")
        self._redraw()
        return target

    def close(self) -> None:
        """Close the figure and forget its callbacks."""
        import matplotlib.pyplot as plt

        self.figure.canvas.mpl_disconnect(self._click_connection)
        plt.close(self.figure)

    # -- internals --

    def _on_press(self, event) -> None:
        toolbar = getattr(self.figure.canvas, "toolbar", None)
        if event.inaxes is not self.section_axes or event.button != 1 or (toolbar is not None and toolbar.mode):
            return  # a zoom or pan, or a click elsewhere
        self.click(float(event.xdata), float(event.ydata))

    def _slider_moved(self, name: str):
        def moved(log_value: float) -> None:
            slider = self.sliders[name]
            slider.valtext.set_text(f"{10.0**log_value:.4g}")
            try:
                scene = rebuild(self.scene, **{name: 10.0**log_value})
            except ValueError as error:
                self._say(f"not rebuilt: {error}")
                self._redraw()
                return
            self.scene = scene
            self.invariants = {**self.chart.default_invariants(scene), **self._given_invariants}
            self._draw_scene_and_survey()
            self._rerun_clicked_orbits()
            self._say(f"{name} = {10.0**log_value:.4g}: {self.survey_message}")
            self._redraw()

        return moved

    def _invariants_text(self) -> str:
        return ", ".join(f"{self.chart.invariant_symbols[k]} = {v:.4g}" for k, v in self.invariants.items())

    def _draw_scene_and_survey(self) -> None:
        ax = self.section_axes
        for line in self._survey_lines + self._edge_lines:
            line.remove()
        started = time.perf_counter()
        states, contacts = self.chart.seeds(self.scene, self.survey_orbits, self.invariants)
        starts = np.asarray(self._section_points(self.scene, states, contacts))[:, None, :]
        points = np.concatenate([starts, *(p for _, p in self._orbit_chunks(states, self.survey_collisions))], 1)
        self.survey_points = points
        seconds = time.perf_counter() - started
        self.survey_message = (
            f"survey of {self.survey_orbits} orbits x {self.survey_collisions} collisions in {seconds:.2f} s"
        )
        import matplotlib

        colormap = matplotlib.colormaps["viridis"]
        self._survey_lines = []
        for i, orbit_points in enumerate(points):
            ok = np.all(np.isfinite(orbit_points), axis=-1)
            (line,) = ax.plot(
                orbit_points[ok, 0],
                orbit_points[ok, 1],
                linestyle="none",
                marker=".",
                markersize=1.3,
                markeredgewidth=0,
                alpha=0.55,
                rasterized=True,
                color=colormap(0.1 + 0.8 * i / max(1, len(points) - 1)),
                zorder=2,
            )
            self._survey_lines.append(line)
        low, high = self.chart.x_range(self.scene)
        across = np.linspace(low, high, 600)
        edge = self.chart.edge(self.scene, across, self.invariants)
        self._edge_lines = [ax.plot(across, edge[:, k], color="k", lw=0.8, zorder=1)[0] for k in (0, 1)]
        finite = edge[np.isfinite(edge)]
        top = float(np.max(np.abs(finite))) if finite.size else 1.0
        ax.set_xlim(low, high)
        ax.set_ylim(-1.04 * top, 1.04 * top)
        ax.set_xlabel(self.chart.axis_labels[0])
        ax.set_ylabel(self.chart.axis_labels[1])
        parameters = ", ".join(f"{k} = {v:.4g}" for k, v in scene_parameters(self.scene).items())
        ax.set_title(
            f"{type(self.scene).__name__}({parameters}): {self.chart.title} at {self._invariants_text()}", fontsize=10
        )

    def _rerun_clicked_orbits(self) -> None:
        """Rerun every clicked orbit from its section point in the new scene, all in one batch."""
        if not self.orbits:
            self._show_survey_orbit()
            return
        starts = np.stack([o.start for o in self.orbits])
        states, contacts = self.chart.start(self.scene, starts[:, 0], starts[:, 1], self.invariants)
        states, contacts = np.asarray(states), np.asarray(contacts)
        reachable = np.all(np.isfinite(states), axis=-1)
        kept_orbits, kept_lines = [], []
        indices = np.flatnonzero(reachable)
        for group in np.array_split(indices, max(1, math.ceil(len(indices) / self.survey_orbits))):
            if not len(group):
                continue
            firsts = np.asarray(self._section_points(self.scene, states[group], contacts[group]))[:, None, :]
            points = np.concatenate(
                [firsts, *(p for _, p in self._orbit_chunks(states[group], self.click_collisions))], 1
            )
            for index, orbit_points in zip(group, points):
                line, marker = self._orbit_lines[index]
                line.set_data(*orbit_points.T)
                kept_orbits.append(
                    ClickedOrbit(self.orbits[index].start, states[index], orbit_points, len(orbit_points) - 1)
                )
                kept_lines.append((line, marker))
        for index in np.flatnonzero(~reachable):
            line, marker = self._orbit_lines[index]
            line.remove()
            marker.remove()
        self.orbits, self._orbit_lines = kept_orbits, kept_lines
        self._show_survey_orbit()
        if self.orbits:
            last = self.orbits[-1]
            orb, _ = next(self._orbit_chunks(last.state0[None], self.chunk))
            head = jax.tree.map(lambda leaf: leaf[0], orb)
            self._draw_configuration(last.state0, head, self._orbit_lines[-1][0].get_color())

    def _show_survey_orbit(self) -> None:
        """The configuration panel before any click: the first survey orbit."""
        states, _ = self.chart.seeds(self.scene, 1, self.invariants)
        orb, _ = next(self._orbit_chunks(states, self.chunk))
        self._draw_configuration(states[0], jax.tree.map(lambda leaf: leaf[0], orb), "0.45")
        self.configuration_axes.set_title(
            f"a survey orbit: its first {self.configuration_collisions} collisions", fontsize=10
        )

    def _orbit_chunks(self, states, collisions: int):
        """Run the orbits from ``states`` (``(k, S)``, ``k <= survey_orbits``) for ``collisions`` collisions.

        Yields, chunk by chunk, the chunk's ``Orbit`` (fields ``(k, chunk, ...)``)
        and its section points ``(k, m, 2)`` (``m = chunk``, less in the last).
        Every call is one batch of ``survey_orbits`` lanes and ``chunk``
        collisions (the lanes past ``k`` repeat the first start), so a single
        compiled program serves the survey, every click and every rerun.
        """
        states = np.asarray(states, dtype=np.float64)
        count = len(states)
        batch = np.concatenate([states, np.repeat(states[:1], self.survey_orbits - count, axis=0)])
        done = 0
        while done < collisions:
            orb = self._run_chunk(self.scene, batch)
            points = np.asarray(self._section_points(self.scene, orb.state, orb.contact))
            keep = min(self.chunk, collisions - done)
            # the first ``count`` orbits, on the host (an Orbit of numpy arrays, for drawing)
            yield jax.device_get(jax.tree_util.tree_map(lambda a: a[:count], orb)), points[:count, :keep]
            done += keep
            batch = np.asarray(orb.state[:, -1])
            if not np.all(np.isfinite(batch)):
                return  # an invalid start poisons its lane with NaN; nothing more to draw

    def _draw_configuration(self, state0, orb, color) -> None:
        ax = self.configuration_axes
        ax.clear()
        count = self.configuration_collisions
        head = Orbit(t=orb.t[:count], contact=orb.contact[:count], state=orb.state[:count], result=orb.result)
        self.chart.draw_configuration(ax, self.scene, np.asarray(state0), head, color)
        ax.set_aspect("equal")
        ax.set_title(f"the last orbit clicked: its first {len(head.t)} collisions", fontsize=10)

    def _say(self, message: str) -> None:
        self.status = message
        self._status_text.set_text(message)

    def _redraw(self) -> None:
        canvas = self.figure.canvas
        if canvas.required_interactive_framework is None:
            return  # Agg and other file canvases draw when saved; a draw here would only cost time
        canvas.draw_idle()
        canvas.flush_events()


# Where ``sample_clicks`` clicks: (fraction across the reachable span, fraction of the half-height up from the
# middle), chosen to land in islands and in a chaotic sea of the default scenes.
SAMPLE_CLICK_FRACTIONS = ((0.25, 0.12), (0.25, 0.5), (0.25, 0.66), (0.45, 0.3), (0.75, 0.75), (0.9, -0.2))


def sample_clicks(explorer: Explorer, count: int = 4) -> list[tuple[float, float]]:
    """``count`` reachable section points of the explorer's panel, at ``SAMPLE_CLICK_FRACTIONS`` (for scripts).

    The fractions are of the span of ``x`` over which the section is
    reachable and of the reachable height at that ``x``.
    """
    if isinstance(count, bool) or not isinstance(count, int) or not 0 <= count <= len(SAMPLE_CLICK_FRACTIONS):
        raise ValueError(f"count must be an integer in [0, {len(SAMPLE_CLICK_FRACTIONS)}]; got {count!r}")
    low, high = explorer.chart.x_range(explorer.scene)
    across = np.linspace(low, high, 801)[1:-1]
    edge = explorer.chart.edge(explorer.scene, across, explorer.invariants)
    reachable = across[np.all(np.isfinite(edge), axis=-1) & (edge[:, 1] > edge[:, 0])]
    clicks = []
    for fx, fy in SAMPLE_CLICK_FRACTIONS[:count]:
        x = float(reachable[0] + fx * (reachable[-1] - reachable[0]))
        bottom, top = explorer.chart.edge(explorer.scene, np.array([x]), explorer.invariants)[0]
        clicks.append((x, float(0.5 * (bottom + top) + 0.5 * fy * (top - bottom))))
    return clicks


def explore(
    scene: HasSection,
    *,
    survey_orbits: int = 24,
    survey_collisions: int = 1000,
    click_collisions: int = 4000,
    chunk: int = 500,
    save_path: str = "jaxbill_explorer.png",
    **invariants: float,
) -> Explorer:
    """Open an interactive explorer of ``scene``'s area-preserving Poincaré section.

    Click in the section panel to start an orbit there; move a slider to
    change a parameter of the scene (the survey and the clicked orbits are
    recomputed); "clear orbits" and "save PNG" do what they say. In Jupyter
    run ``%matplotlib widget`` first (``pip install ipympl``); in a script
    call ``matplotlib.pyplot.show()`` after it. Details: ``jaxbill._explorer``.

    Args:
        scene: one scene with a section, that is any scene that provides a
            ``SectionChart``; every scene of jaxbill does: ``StickInCircle``
            (the reduced section ``(s, p)``, for the lens and the circle their
            Birkhoff section), ``StickInEllipse`` (the Birkhoff section of the
            touching end), ``StickBetweenWalls2D`` (the floor section ``(theta
            mod pi, p)``), ``StickBetweenWalls3D`` (the reduced floor section
            at fixed ``I w_z``), ...
        survey_orbits: orbits in the survey, started evenly over the section.
        survey_collisions: collisions of each survey orbit.
        click_collisions: collisions of each clicked orbit.
        chunk: collisions per drawing step of a clicked orbit.
        save_path: where "save PNG" writes (default ``./jaxbill_explorer.png``).
        **invariants: the section's fixed quantities, named by the chart's
            ``invariant_symbols`` (``StickInCircle``: ``energy`` ``E``, default
            0.5, and ``angular_momentum`` ``L``, default 0; ``StickInEllipse``:
            ``energy`` ``E``, default 0.5; the walls: ``energy`` ``E'``, default
            0.5, and in 3D ``spin`` ``I w_z``, default ``0.6 sqrt(I)``).

    Returns:
        The ``Explorer``: its ``figure``, ``click(x, y)``,
        ``set_parameter(name, value)``, ``clear()``, ``save(path)``.

    Raises:
        TypeError: for a scene without a section.
        ValueError: for a batch of scenes, an unknown invariant, or a count
            that is not an integer >= 1.
    """
    return Explorer(
        scene,
        invariants,
        survey_orbits=survey_orbits,
        survey_collisions=survey_collisions,
        click_collisions=click_collisions,
        chunk=chunk,
        save_path=save_path,
    )
