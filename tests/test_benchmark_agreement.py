"""The GPU benchmark's agreement check: a row that computes something wrong must say FAIL.

``benchmarks/agreement.py`` compares jaxbill's final states (and contact
sequences) with the numba kernel's from the same states. Its verdicts are
checked here on states with known differences: a perturbation above the
tolerance, a share of split orbits above the allowed one, an angle that differs
by a whole turn, a NaN. With numba installed (the ``bench`` extra), jaxbill's
drivers are also checked against numba's CPU loop, the CUDA kernel's device code
line for line.
"""

from __future__ import annotations

import pathlib
import sys

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))
import agreement  # noqa: E402

ORBITS = 4000


def _states(seed=0):
    return np.random.default_rng(seed).normal(size=(ORBITS, 6))


def _finals(perturbed=0, by=0.0, angle_turns=0, nan_rows=0):
    """A fake kernel: ``(states, n) -> states + n`` with ``perturbed`` rows moved by ``by`` in x."""

    def final_states_of(states, n):
        out = states + float(n)
        out[:perturbed, 0] += by
        out[:, 2] += 2.0 * np.pi * angle_turns
        out[:nan_rows] = np.nan
        return out

    return final_states_of


def test_identical_results_pass():
    assert agreement.disagreements(_finals(), _finals(), _states(), 200) == []
    assert agreement.verdict([]) == "PASS"


def test_an_angle_a_whole_turn_away_is_the_same_state():
    assert agreement.disagreements(_finals(angle_turns=3), _finals(), _states(), 200) == []


def test_a_share_of_split_orbits_above_the_allowed_one_fails():
    split = int(0.01 * ORBITS)  # 1 %, ten times the allowed share
    problems = agreement.disagreements(_finals(split, 1e-8), _finals(), _states(), 200)
    assert len(problems) == 1 and problems[0].startswith("1.0% of final states after 5 collisions")
    assert agreement.verdict(problems).startswith("**FAIL**")


def test_a_few_grazing_splits_and_differences_below_the_tolerance_pass():
    few = int(0.5 * agreement.ALLOWED_SPLIT * ORBITS)
    assert agreement.disagreements(_finals(few, 1.0), _finals(), _states(), 200) == []
    assert agreement.disagreements(_finals(ORBITS, 1e-12), _finals(), _states(), 200) == []


def test_nan_where_the_reference_is_finite_fails():
    problems = agreement.disagreements(_finals(nan_rows=1), _finals(), _states(), 200)
    assert any("1 final states after 200 collisions are NaN" in problem for problem in problems)


def test_differing_contact_sequences_fail():
    def contacts(states, n):
        return np.ones((len(states), n), np.int32)

    def other(states, n):
        codes = contacts(states, n)
        codes[: len(states) // 2, -1] = 2
        return codes

    problems = agreement.disagreements(_finals(), _finals(), _states(), 200, contacts, other)
    assert problems == [f"50.0% of {agreement.CONTACT_SAMPLE} contact sequences over 5 collisions differ"]
    assert agreement.disagreements(_finals(), _finals(), _states(), 200, contacts, contacts) == []


@pytest.mark.parametrize("scene_name", ["rotor R=2 ell=1.9", "lens R=2 ell=1.5", "walls h=3 ell=1"])
def test_jaxbill_agrees_with_the_numba_loop(scene_name):
    """jaxbill's lanes driver against numba's CPU loop (the CUDA kernel's device code), as the GPU benchmark
    checks its rows; needs numba (the ``bench`` extra)."""
    pytest.importorskip("numba")
    import jaxbill as jb
    import numba_baseline as baseline

    params = baseline.CHECK_SCENES[scene_name]
    scene = baseline.jaxbill_scene(params)
    states = baseline.random_states(params, 64, seed=5)

    def jaxbill_finals(states, n):
        return jb.run(scene, states, n, driver="lanes", progress=False).final_state

    def numba_finals(states, n):
        return baseline.run_batch(params, states, n)[0]

    def jaxbill_contacts(states, n):
        return np.asarray(jb.orbit(scene, states, n).contact)

    def numba_contacts(states, n):
        return np.stack([baseline.orbit(params, state, n)[1] for state in states])

    assert agreement.disagreements(jaxbill_finals, numba_finals, states, 60, jaxbill_contacts, numba_contacts) == []
