"""What both checkers share: the certificate that a gap stays positive over a step, and the report
comparing a checker's collisions with ``jb.orbit``."""

from __future__ import annotations

import dataclasses
import math
import time

import jax.numpy as jnp
import numpy as np
from jaxtyping import Float, Int


def certified_positive(f0, p0, f1, p1, h, K):
    """True where ``f > 0`` on the open step ``(0, h)`` is proven.

    ``f0, p0`` (``f1, p1``) are value and slope at the step's start (end) and
    ``|f''| <= K``. Taylor bounds from the left and from the right prove
    positivity on ``(0, sL)`` and ``(h - sR, h)``; the interpolation bound
    ``f >= lin - K s (h - s) / 2`` covers what is left between them.
    """
    K = jnp.maximum(K, 1e-300)
    sL = jnp.where(f0 >= 0.0, (p0 + jnp.sqrt(jnp.maximum(p0 * p0 + 2.0 * K * f0, 0.0))) / K, 0.0)
    sR = jnp.where(f1 >= 0.0, (-p1 + jnp.sqrt(jnp.maximum(p1 * p1 + 2.0 * K * f1, 0.0))) / K, 0.0)
    covered = sL + sR > h
    lo, hi = jnp.minimum(sL, h), jnp.maximum(h - sR, 0.0)
    s = jnp.clip(0.5 * h - (f1 - f0) / (K * h), lo, hi)
    interp = f0 + (f1 - f0) * s / h - 0.5 * K * s * (h - s)
    return (f0 >= 0.0) & (f1 >= 0.0) & (covered | ((interp > 0.0) & (h > 0.0)) | (h == 0.0))


# ---------------------------------------------------------------------------
# results
# ---------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class CheckFlag:
    """Where the checker stopped trusting itself: collision ``index`` (0-based,
    the one that could not be certified), a ``kind`` from ``graze``,
    ``max_steps``, ``root_find``, ``not_approaching``, ``corner``, ``curvature``
    (a wall bent more than the bound that certifies the steps), and a message."""

    index: int
    kind: str
    message: str


@dataclasses.dataclass(frozen=True)
class CheckReport:
    """Comparison of the checker's collisions with ``jb.orbit``.

    Deviations are the largest over the compared collisions, each in scaled
    units: time in ``R / V``, position in ``R``, ``alpha`` in radians (mod 2 pi),
    velocity in ``V`` and spin in ``V / sqrt(I/M)`` (``V / R`` for a point or a
    body that never turns), ``V = sqrt(2 E / M)`` the speed scale of the orbit
    and ``R`` the flight's unit of length (the circle's radius, the table's size).
    """

    n: int  # collisions asked for
    n_checked: int  # collisions the checker certified
    horizon: int  # collisions before a 1e-12-perturbed jb.orbit departs by > tol
    n_compared: int  # min(n_checked, horizon)
    tol: float
    max_time: float
    max_position: float
    max_angle: float
    max_velocity: float
    max_spin: float
    first_contact_mismatch: int | None
    first_deviation: int | None  # first index with a scaled deviation > tol
    # One-collision comparison over all certified collisions (no chaos horizon):
    # jb.collide from the checker's state i-1 against the checker's collision i.
    local_max_time: float
    local_max_state: float  # largest scaled position/angle/velocity/spin deviation
    local_first_mismatch: int | None  # first i with another contact or a deviation > tol
    flags: tuple
    n_steps: int
    seconds: float

    @property
    def agree(self) -> bool:
        """Contacts equal and every scaled deviation within ``tol`` up to ``n_compared``."""
        return (
            self.first_contact_mismatch is None and self.first_deviation is None and self.local_first_mismatch is None
        )

    @property
    def trusted(self) -> bool:
        """The checker certified all ``n`` collisions (no flag)."""
        return not self.flags

    def __str__(self) -> str:
        lines = [
            f"jaxbill.check: {self.n_checked}/{self.n} collisions certified, "
            f"{self.n_compared} compared (chaos horizon {self.horizon}), "
            f"{self.n_steps} solver steps, {self.seconds:.2f} s",
            f"  max deviation (scaled): time {self.max_time:.2e}  position {self.max_position:.2e}  "
            f"angle {self.max_angle:.2e}  velocity {self.max_velocity:.2e}  spin {self.max_spin:.2e}",
            f"  one collision at a time, all {self.n_checked}: time {self.local_max_time:.2e}  "
            f"state {self.local_max_state:.2e}"
            + ("" if self.local_first_mismatch is None else f"  MISMATCH from {self.local_first_mismatch}"),
            "  contacts: "
            + (
                "all equal"
                if self.first_contact_mismatch is None
                else f"first mismatch at {self.first_contact_mismatch}"
            ),
            "  verdict: "
            + ("AGREE" if self.agree else "DISAGREE")
            + f" within tol {self.tol:.1e}"
            + ("" if self.first_deviation is None else f" (first deviation > tol at {self.first_deviation})"),
        ]
        for f in self.flags:
            lines.append(f"  FLAG at collision {f.index} [{f.kind}]: {f.message}")
        return "\n".join(lines)


@dataclasses.dataclass(frozen=True)
class CheckResult:
    """The checker's own collision sequence (``t`` (m,), ``contact`` (m,),
    ``state`` (m, 6), the usual layout, state just after each collision, alpha
    wrapped into ``[-pi, pi)``; ``m <= n`` certified collisions), the reference
    ``orbit`` from ``jb.orbit`` and the comparison ``report``."""

    t: Float[np.ndarray, " m"]
    contact: Int[np.ndarray, " m"]
    state: Float[np.ndarray, "m S"]
    orbit: object
    report: CheckReport

    def __str__(self) -> str:
        return str(self.report)


def comparison_report(n, contact, ref_contact, horizon, tol, dev, local_max, local_bad, flags, n_steps, start):
    """The ``CheckReport`` of a checker run: ``dev`` holds the scaled deviations
    ``(m, 5)`` of its first ``m = min(collisions checked, horizon)`` collisions."""
    m = len(dev)
    maxima = dev.max(axis=0) if m else np.zeros(5)
    return CheckReport(
        n=n,
        n_checked=len(contact),
        horizon=horizon,
        n_compared=m,
        tol=tol,
        max_time=float(maxima[0]),
        max_position=float(maxima[1]),
        max_angle=float(maxima[2]),
        max_velocity=float(maxima[3]),
        max_spin=float(maxima[4]),
        first_contact_mismatch=first_index(contact[:m] != ref_contact[:m]),
        first_deviation=first_index(np.any(dev > tol, axis=1)),
        local_max_time=float(local_max[0]),
        local_max_state=float(local_max[1:].max()),
        local_first_mismatch=first_index(local_bad),
        flags=tuple(flags),
        n_steps=n_steps,
        seconds=time.perf_counter() - start,
    )


def wrap_angle(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


def first_index(mask):
    idx = np.flatnonzero(mask)
    return int(idx[0]) if idx.size else None
