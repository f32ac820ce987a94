"""``jaxbill figures --quick``: every promised file is written, and the summary's numbers are true.

The summary's numbers are recomputed here directly: each panel's orbits are
run again with ``jb.orbit`` from the start states the summary records (in the
same batch as the figure ran them: beside twins whose velocity is turned by
1e-11 rad, where the summary says so), and the collision counts and the worst
energy and angular-momentum drift are computed from the definitions (not with
``jaxbill._figures``).
"""

from __future__ import annotations

import json
import math
import subprocess
import sys

import jax
import numpy as np
import pytest

import jaxbill as jb
from jaxbill import cli
from jaxbill._figures import COMPOSITIONS_FILES, ELLIPSE_FILES, FILES, WALLS_FILES


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("figures")
    assert cli.main(["figures", "--quick", "--no-progress", "--out", str(out)]) == 0
    with open(out / "summary.json") as handle:
        return out, json.load(handle)


def test_every_promised_file_is_written(quick_run):
    out, summary = quick_run
    for name in FILES:
        path = out / name
        assert path.is_file(), name
        assert path.stat().st_size > 1000, name
        if name.endswith(".png"):
            assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
    written = {figure["file"] for figure in summary["figures"]}
    assert written == {name for name in FILES if name.endswith(".png")}
    text = (out / "summary.txt").read_text()
    for name in written:
        assert name in text
    assert summary["quick"] is True


def _scene(record):
    inertia = record["inertia"]
    inertia = math.inf if inertia == "inf" else inertia
    return jb.StickInCircle(R=record["R"], ell=record["ell"], mass=record["mass"], inertia=inertia)


def _panels(summary):
    return [(figure["file"], panel) for figure in summary["figures"] for panel in figure["panels"]]


def test_summary_parameters_match_the_paper(quick_run):
    _, summary = quick_run
    by_file = {}
    for name, panel in _panels(summary):
        by_file.setdefault(name, []).append(panel)
    (fig1,) = by_file["fig1_trajectory.png"]
    assert (fig1["scene"]["R"], fig1["scene"]["ell"]) == (2.0, 1.0)
    (fig2,) = by_file["fig2_projected_section.png"]
    assert (fig2["scene"]["R"], fig2["scene"]["ell"], fig2["orbits"]) == (2.0, 1.9, 2)
    assert fig2["orbit_kinds"] == ["regular", "chaotic"]
    (fig3,) = by_file["fig3_lens_section.png"]
    assert (fig3["scene"]["ell"], fig3["scene"]["inertia"], fig3["scene"]["kind"]) == (1.5, "inf", "lens")
    assert [p["scene"]["ell"] for p in by_file["ell_scan.png"]] == [1.9, 1.5, 1.1, 0.5, 0.1]
    inertias = [p["scene"]["inertia"] / p["scene"]["ell"] ** 2 for p in by_file["inertia_scan.png"]]
    np.testing.assert_allclose(inertias, [1.0, 1 / 100, 1 / 200], rtol=1e-12)


def test_summary_numbers_match_a_direct_computation(quick_run):
    _, summary = quick_run
    worst_energy, worst_momentum, total = 0.0, 0.0, 0
    for name, panel in _panels(summary):
        scene = _scene(panel["scene"])
        states0 = np.asarray(panel["states0"])
        n = panel["collisions_per_orbit"]
        if panel["twins"]:
            # the figure ran each orbit beside a twin with its velocity turned by 1e-11 rad, in one batch
            delta = 1e-11
            twins = states0.copy()
            twins[:, 3] = math.cos(delta) * states0[:, 3] - math.sin(delta) * states0[:, 4]
            twins[:, 4] = math.sin(delta) * states0[:, 3] + math.cos(delta) * states0[:, 4]
            orb = jb.orbit(scene, np.concatenate([states0, twins]), n)
            orb = jax.tree_util.tree_map(lambda a: a[: len(states0)], orb)
        else:
            orb = jb.orbit(scene, states0 if len(states0) > 1 else states0[0], n)
        states = np.asarray(orb.state).reshape(len(states0), n, 6)
        assert panel["orbits"] == len(states0)
        assert panel["collisions"] == len(states0) * n
        assert np.all(np.isfinite(states))
        assert panel["missed_or_failed"] == int(np.sum(np.asarray(orb.contact) == 0)) == 0
        # energy M |v|^2 / 2 + I omega^2 / 2 (no spin term for the lens)
        spin = 0.0 if scene.kind == "lens" else float(scene.inertia)
        e = 0.5 * float(scene.mass) * (states[..., 3] ** 2 + states[..., 4] ** 2) + 0.5 * spin * states[..., 5] ** 2
        e0 = 0.5 * float(scene.mass) * (states0[:, 3] ** 2 + states0[:, 4] ** 2) + 0.5 * spin * states0[:, 5] ** 2
        energy_drift = np.max(np.abs(e / e0[:, None] - 1))
        assert panel["energy_drift"] == pytest.approx(energy_drift, rel=1e-9, abs=1e-16)
        assert energy_drift < 1e-11
        worst_energy = max(worst_energy, energy_drift)
        if scene.kind == "lens":
            assert panel["angular_momentum_drift"] is None
        else:

            def momentum(s):
                return float(scene.mass) * (s[..., 0] * s[..., 4] - s[..., 1] * s[..., 3]) + spin * s[..., 5]

            scale = float(scene.R) * np.sqrt(2 * float(scene.mass) * e0)
            drift = np.max(np.abs(momentum(states) - momentum(states0)[:, None]) / scale[:, None])
            assert panel["angular_momentum_drift"] == pytest.approx(drift, rel=1e-9, abs=1e-16)
            assert drift < 1e-12
            worst_momentum = max(worst_momentum, drift)
        if name not in ("spiral_column.png", "fig2_reduced_vs_projected.png"):
            total += panel["collisions"]
    assert summary["worst_energy_drift"] == pytest.approx(worst_energy, rel=1e-12)
    assert summary["worst_angular_momentum_drift"] == pytest.approx(worst_momentum, rel=1e-12)
    assert summary["total_collisions"] == total


def test_section_orbits_hold_one_energy_and_momentum(quick_run):
    _, summary = quick_run
    for name, panel in _panels(summary):
        if name in ("fig1_trajectory.png", "spiral_column.png"):
            continue
        assert panel["energy"] == pytest.approx(0.5, abs=1e-12)
        if panel["scene"]["kind"] != "lens":
            assert panel["angular_momentum"] == pytest.approx(0.0, abs=1e-12)


def test_demo_still_works(capsys):
    assert cli.main(["demo", "-n", "20", "--show", "2"]) == 0
    assert "angular momentum" in capsys.readouterr().out


def test_console_command_offers_figures():
    result = subprocess.run(
        [sys.executable, "-m", "jaxbill.cli", "figures", "--help"], capture_output=True, text=True, check=True
    )
    assert "--out" in result.stdout and "--quick" in result.stdout


# -- the stick between two flat walls (summary["walls"]) ---------------------------------


def _walls_scene(record):
    cls = jb.StickBetweenWalls3D if record["dimension"] == 3 else jb.StickBetweenWalls2D
    return cls(record["h"], record["ell"], mass=record["mass"], inertia=record["inertia"])


def _walls_twins(scene, states0, delta):
    """Twins by the definition: (theta_dot, z_dot / kappa) turned by delta; in 3D the polar rate is w . e_phi."""
    kappa = math.sqrt(float(scene.inertia) / float(scene.mass))
    c, s = math.cos(delta), math.sin(delta)
    twins = states0.copy()
    if states0.shape[1] == 12:
        u, w = states0[:, 3:6], states0[:, 9:12]
        e_phi = np.stack([-u[:, 1], u[:, 0], np.zeros(len(u))], axis=1) / np.hypot(u[:, 0], u[:, 1])[:, None]
        rate, eta_dot = np.sum(w * e_phi, axis=1), states0[:, 8] / kappa
        twins[:, 9:12] = w + ((c * rate - s * eta_dot) - rate)[:, None] * e_phi
        twins[:, 8] = kappa * (s * rate + c * eta_dot)
    else:
        rate, eta_dot = states0[:, 5], states0[:, 4] / kappa
        twins[:, 5] = c * rate - s * eta_dot
        twins[:, 4] = kappa * (s * rate + c * eta_dot)
    return twins


def test_ellipse_figure_is_written(quick_run):
    """``ellipse.png`` and its record: the energy, the ellipse's only invariant, kept to rounding."""
    out, summary = quick_run
    assert [figure["file"] for figure in summary["ellipse"]] == list(ELLIPSE_FILES)
    path = out / ELLIPSE_FILES[0]
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 1000
    assert ELLIPSE_FILES[0] in (out / "summary.txt").read_text()
    panels = summary["ellipse"][0]["panels"]
    assert [panel["scene"]["kind"] for panel in panels] == ["point", "rotor"]
    for panel in panels:
        assert panel["collisions"] == panel["orbits"] * panel["collisions_per_orbit"] > 0
        assert panel["energy_drift"] < 1e-12


def test_compositions_figure_is_written(quick_run):
    """``compositions.png`` and its record: each panel's orbit, run again from its recorded start in a scene built
    here from the public API, has the recorded length and drift and keeps the energy ``M |v|^2 / 2 + I omega^2 / 2``
    to rounding; every start has ``E = 1/2`` (the coin: ``E' = 1/2`` without its sideways motion)."""
    out, summary = quick_run
    assert [figure["file"] for figure in summary["compositions"]] == list(COMPOSITIONS_FILES)
    path = out / COMPOSITIONS_FILES[0]
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 1000
    assert COMPOSITIONS_FILES[0] in (out / "summary.txt").read_text()
    stadium = jb.Stadium(1.0, 1.0)
    scenes = {
        ("PolygonBody.regular(3, 0.3)", "Stadium(1, 1)"): jb.BodyInTable(jb.PolygonBody.regular(3, 0.3), stadium),
        ("Dumbbell.from_masses(0.25, 0.75, 1)", "Ellipse(2, 1.3)"): jb.BodyInTable(
            jb.Dumbbell.from_masses(0.25, 0.75, 1.0), jb.Ellipse(2.0, 1.3)
        ),
        ("PolygonBody.regular(4, 0.5)", "Circle(1)"): jb.BodyInTable(jb.PolygonBody.regular(4, 0.5), jb.Circle(1.0)),
        ("PointBody()", "Stadium(1, 1)"): jb.BodyInTable(jb.PointBody(), stadium),
        ("EllipseBody(1, 0.5)", "Strip(4)"): jb.BodyInTable(jb.EllipseBody(1.0, 0.5), jb.Strip(4.0)),
    }
    panels = summary["compositions"][0]["panels"]
    assert [(panel["body"], panel["table"]) for panel in panels] == list(scenes)
    for panel in panels:
        scene = scenes[(panel["body"], panel["table"])]
        state0 = np.asarray(panel["state0"])
        n = panel["collisions"]
        orb = jb.orbit(scene, state0, n)
        states, contact = np.asarray(orb.state), np.asarray(orb.contact)
        assert states.shape == (n, 6) and np.all(np.isfinite(states))
        assert panel["missed_or_failed"] == int(np.sum(contact == 0)) == 0
        mass, inertia = float(scene.body.mass), float(scene.body.inertia)

        def energy(s):
            return 0.5 * mass * (s[..., 3] ** 2 + s[..., 4] ** 2) + 0.5 * inertia * s[..., 5] ** 2

        sideways = 0.5 * mass * state0[3] ** 2 if panel["table"].startswith("Strip") else 0.0
        assert energy(state0) - sideways == pytest.approx(0.5, abs=1e-12)
        assert panel["energy"] == pytest.approx(energy(state0), rel=1e-12)
        drift = np.max(np.abs(energy(states) / energy(state0) - 1))
        # the two energy formulas may round apart by an ulp or two of E
        assert panel["energy_drift"] == pytest.approx(drift, abs=5e-16)
        assert drift < 1e-12
    assert [panel["kind"] for panel in panels] == ["rotor", "rotor", "rotor", "point", "rotor"]


def test_walls_figures_are_written(quick_run):
    out, summary = quick_run
    assert {figure["file"] for figure in summary["walls"]} == set(WALLS_FILES)
    text = (out / "summary.txt").read_text()
    for name in WALLS_FILES:
        path = out / name
        assert path.is_file() and path.stat().st_size > 1000, name
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
        assert name in text
    sections = next(f for f in summary["walls"] if f["file"] == "walls_sections.png")["panels"]
    heights = [1.5, 2.05, 2.5, 3.0, 4.0, 8.0]
    assert [p["scene"]["h"] for p in sections if p["scene"]["dimension"] == 2] == heights
    assert [p["scene"]["h"] for p in sections if p["scene"]["dimension"] == 3] == heights
    for panel in sections:
        assert panel["scene"]["ell"] == 1.0 and panel["scene"]["inertia"] == pytest.approx(1.0)
        if panel["scene"]["dimension"] == 2:
            # the 2D stick between walls is a dispersing billiard: every orbit is chaotic, at every h
            assert panel["chaotic_fraction"] == 1.0
        else:
            assert panel["spin"] == pytest.approx(0.6, abs=1e-12)  # 0.6 sqrt(2 I E') with I = 1, E' = 1/2
            assert 0.0 <= panel["chaotic_fraction"] <= 1.0


def test_walls_summary_numbers_match_a_direct_computation(quick_run):
    _, summary = quick_run
    worst_energy, worst_momentum = 0.0, 0.0
    for figure in summary["walls"]:
        for panel in figure["panels"]:
            scene = _walls_scene(panel["scene"])
            states0 = np.asarray(panel["states0"])
            n, count = panel["collisions_per_orbit"], len(states0)
            assert panel["twins"]
            orb = jb.orbit(scene, np.concatenate([states0, _walls_twins(scene, states0, panel["twin_delta"])]), n)
            states = np.asarray(orb.state)[:count]
            contact = np.asarray(orb.contact)[:count]
            assert panel["orbits"] == count and panel["collisions"] == count * n
            assert np.all(np.isfinite(states))
            assert panel["missed_or_failed"] == int(np.sum(contact == 0)) == 0
            assert panel["several_contacts"] == int(np.sum(contact == 2))
            mass, inertia = float(scene.mass), float(scene.inertia)
            if states0.shape[1] == 12:

                def energy(s):
                    return 0.5 * mass * np.sum(s[..., 6:9] ** 2, -1) + 0.5 * inertia * np.sum(s[..., 9:12] ** 2, -1)

                def momentum(s):
                    return mass * (s[..., 0] * s[..., 7] - s[..., 1] * s[..., 6]) + inertia * s[..., 11]

                unit = np.sqrt(2 * inertia * energy(states0))
                low_end = states[..., 2] - float(scene.ell) * np.abs(states[..., 5])  # the lower end's height
            else:

                def energy(s):
                    return 0.5 * mass * (s[..., 3] ** 2 + s[..., 4] ** 2) + 0.5 * inertia * s[..., 5] ** 2

                def momentum(s):
                    return mass * s[..., 3]

                unit = np.sqrt(2 * mass * energy(states0))
                low_end = states[..., 1] - float(scene.ell) * np.abs(np.cos(states[..., 2]))
            assert panel["energy"] == pytest.approx(0.5, abs=1e-12)  # no horizontal motion: E = E'
            e0 = energy(states0)
            drift = np.max(np.abs(energy(states) / e0[:, None] - 1))
            assert panel["energy_drift"] == pytest.approx(drift, rel=1e-9, abs=1e-16)
            assert drift < 1e-11
            p_drift = np.max(np.abs(momentum(states) - momentum(states0)[:, None]) / unit[:, None])
            assert panel["momentum_drift"] == pytest.approx(p_drift, rel=1e-9, abs=1e-16)
            assert p_drift < 1e-12
            # floor collisions: an end on the floor (contacts +-1, or 2 with the lower end at z = 0)
            floor = (np.abs(contact) == 1) | ((contact == 2) & (np.abs(low_end) < 1e-9))
            assert panel["floor_collisions"] == int(np.sum(floor))
            assert 0.3 * count * n < panel["floor_collisions"] < 0.7 * count * n
            worst_energy, worst_momentum = max(worst_energy, drift), max(worst_momentum, p_drift)
    assert summary["walls_worst_energy_drift"] == pytest.approx(worst_energy, rel=1e-12)
    assert summary["walls_worst_momentum_drift"] == pytest.approx(worst_momentum, rel=1e-12, abs=1e-300)
