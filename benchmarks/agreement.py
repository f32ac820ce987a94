"""Whether jaxbill's results agree with the numba kernel's from the same states: a verdict per timed row.

A benchmark that times a wrong result can look fast; ``bench_gpu.py`` passes every
row it times through ``verdict`` and says FAIL loudly (and exits non-zero) when:

* over the first ``CHECK_COLLISIONS`` collisions, within the chaos horizon (a
  rounding difference grows by ``exp(lambda k)``: between two walls about tenfold
  a collision, from 1e-15 after one collision to 1e-12 after five and 1e-9 after
  ten; ``numba_baseline.check_against_jaxbill`` measures the horizon), the final
  states differ by more than ``TOLERANCE`` (``relative_difference``:
  relative to ``max(1, |x|)``, angles modulo 2 pi) on more than ``ALLOWED_SPLIT``
  of the orbits (a contact that grazes a wall within both root searches'
  precision may go either way, and then the orbits part for good);
* on a sample of ``CONTACT_SAMPLE`` orbits, ``jb.orbit``'s contact sequence over
  those collisions differs from numba's on more than that share;
* after all ``n`` collisions, a final state is NaN where numba's is finite.

Without a GPU the same checks run against numba's CPU loop, which is the CUDA
kernel's device code line for line (``numba_cuda_baseline.check_against_cpu``).
"""

from __future__ import annotations

import numpy as np

CHECK_COLLISIONS = 5
TOLERANCE = 1e-10
ALLOWED_SPLIT = 1e-3
CONTACT_SAMPLE = 256


def relative_difference(a, b):
    """Per state (last axis): max over its components of ``|a - b| / max(1, |b|)``, the angle (component 2)
    compared modulo 2 pi."""
    diff = np.abs(a - b)
    angle = np.abs(np.remainder(a[..., 2] - b[..., 2] + np.pi, 2 * np.pi) - np.pi)
    diff[..., 2] = angle
    return np.max(diff / np.maximum(1.0, np.abs(b)), axis=-1)


def split_share(ours, theirs):
    """The share of orbits whose states ``(B, 6)`` differ by more than ``TOLERANCE``, or are NaN in ``ours``."""
    diff = relative_difference(np.asarray(ours, np.float64), np.asarray(theirs, np.float64))
    return float(np.mean(~(diff <= TOLERANCE)))


def disagreements(final_states_of, reference_final_states, states, n, contacts_of=None, reference_contacts=None):
    """What disagrees between jaxbill and the numba kernel from ``states`` ``(B, 6)``; an empty list when all
    agrees.

    Args:
        final_states_of: ``(states, collisions) -> (B, 6)`` jaxbill's final states
            (the timed row's own call).
        reference_final_states: ``(states, collisions) -> (B, 6)``: the numba
            kernel's (CUDA, or the CPU loop).
        states: ``(B, 6)`` float64 starts; n: the row's collisions.
        contacts_of, reference_contacts: ``(states, collisions) -> (b, collisions)``
            contact codes, jaxbill's (``jb.orbit``) and numba's, or None to leave
            the contact sequences out.
    """
    problems = []
    short = min(n, CHECK_COLLISIONS)
    share = split_share(final_states_of(states, short), reference_final_states(states, short))
    if share > ALLOWED_SPLIT:
        problems.append(f"{share:.1%} of final states after {short} collisions differ by more than {TOLERANCE:g}")
    if contacts_of is not None and reference_contacts is not None:
        sample = states[:CONTACT_SAMPLE]
        ours, theirs = np.asarray(contacts_of(sample, short)), np.asarray(reference_contacts(sample, short))
        differing = float(np.mean(np.any(ours != theirs, axis=-1)))
        if differing > ALLOWED_SPLIT:
            problems.append(f"{differing:.1%} of {len(sample)} contact sequences over {short} collisions differ")
    ours, theirs = np.asarray(final_states_of(states, n)), np.asarray(reference_final_states(states, n))
    lost = int(np.sum(np.any(np.isnan(ours), axis=-1) & np.all(np.isfinite(theirs), axis=-1)))
    if lost:
        problems.append(f"{lost} final states after {n} collisions are NaN where numba's are finite")
    return problems


def verdict(problems):
    """One line for the table: PASS, or FAIL and what disagreed."""
    return "PASS" if not problems else "**FAIL**: " + "; ".join(problems)
