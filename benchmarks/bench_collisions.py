"""Collision throughput of ``jb.orbit`` against a plain scipy ``solve_ivp`` event loop.

Run:  python benchmarks/bench_collisions.py [--quick] [--repeats N]

Prints machine info and a markdown table of collisions per second of
``jb.orbit(scene, states0, n)`` for batches of 1, 1024 and 16384 orbits (float64),
compile time reported separately (first call minus steady state; steady state is
the median of several timed runs after compilation), and, for each scene, a
scipy ``solve_ivp`` (DOP853, rtol = atol = 1e-12, terminal events) loop on one
orbit, with its collision-time deviation from jaxbill so that the comparison
is at equal accuracy. Targets are printed beside the measurements. Nothing here
asserts on timings.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import statistics
import sys
import time

import numpy as np
from scipy.integrate import solve_ivp

# Scenes benchmarked: (label, R, ell, inertia); inertia None -> default M ell^2.
SCENES = [
    ("R=2 ell=1.9 I=M ell^2", 2.0, 1.9, None),
    ("R=2 ell=1.0 I=M ell^2", 2.0, 1.0, None),
    ("R=2 ell=1.9 I=inf", 2.0, 1.9, float("inf")),
    ("R=2 ell=1.0 I=inf", 2.0, 1.0, float("inf")),
]
MASS = 1.0
BATCHES = (1, 1024, 16384)

TARGET_ROTOR_BATCH = 3e6  # ell = 1.9, default inertia, B = 16384
TARGET_LENS_BATCH = 2e7  # infinite inertia, B = 16384
TARGET_SINGLE = 1e6  # single orbit (B = 1)
TARGET_SCIPY_RATIO = 1000.0  # jaxbill single orbit / scipy loop


# --------------------------------------------------------------------------------------
# Initial states (numpy, seeded)
# --------------------------------------------------------------------------------------
def random_states(R, ell, inertia, batch, seed, margin=1e-3):
    """Random valid states, shape (batch, 6): centre inside, both ends strictly inside
    the circle (|P_k| <= R - margin), translational energy M|v|^2/2 = 1 with a random
    direction, omega ~ U(-1, 1) (omega = 0 for infinite inertia)."""
    rng = np.random.default_rng(seed)
    out = np.empty((0, 6))
    while out.shape[0] < batch:
        m = 4 * (batch - out.shape[0]) + 64
        r = R * np.sqrt(rng.uniform(0.0, 1.0, m))
        th = rng.uniform(-np.pi, np.pi, m)
        x, y = r * np.cos(th), r * np.sin(th)
        a = rng.uniform(-np.pi, np.pi, m)
        ux, uy = np.cos(a), np.sin(a)
        p1 = np.hypot(x + ell * ux, y + ell * uy)
        p2 = np.hypot(x - ell * ux, y - ell * uy)
        ok = (p1 <= R - margin) & (p2 <= R - margin)
        phi = rng.uniform(-np.pi, np.pi, m)
        speed = math.sqrt(2.0 / MASS)
        vx, vy = speed * np.cos(phi), speed * np.sin(phi)
        if inertia is not None and math.isinf(inertia):
            om = np.zeros(m)
        else:
            om = rng.uniform(-1.0, 1.0, m)
        s = np.stack([x, y, a, vx, vy, om], axis=1)[ok]
        out = np.concatenate([out, s], axis=0)
    return out[:batch]


# --------------------------------------------------------------------------------------
# The scipy loop: what one writes without jaxbill
# --------------------------------------------------------------------------------------
def _rhs(t, q):
    return np.array([q[3], q[4], q[5], 0.0, 0.0, 0.0])


def _make_gap(R, ell, k):
    R2 = R * R

    def g(t, q):
        px = q[0] + k * ell * math.cos(q[2])
        py = q[1] + k * ell * math.sin(q[2])
        return R2 - (px * px + py * py)

    g.terminal = True
    g.direction = -1
    return g


def impulse(q, k, R, ell, M, inertia):
    """Frictionless elastic impulse at end k."""
    x, y, a, vx, vy, om = q
    ux, uy = math.cos(a), math.sin(a)
    px, py = x + k * ell * ux, y + k * ell * uy
    rp = math.hypot(px, py)
    nx, ny = px / rp, py / rp
    s = k * ell * (ux * ny - uy * nx)
    vn = vx * nx + vy * ny + om * s
    inv_i = 0.0 if math.isinf(inertia) else 1.0 / inertia
    J = 2.0 * vn / (1.0 / M + s * s * inv_i)
    return np.array([x, y, a, vx - J / M * nx, vy - J / M * ny, om - J * inv_i * s])


def scipy_orbit(R, ell, inertia, q0, n, rtol=1e-12, atol=1e-12, step_frac=0.1):
    """n collisions by solve_ivp(DOP853) with terminal events g_k = R^2 - |P_k|^2.

    max_step limits the motion of any end point per step to step_frac * R, so that a
    step does not jump over an exit and re-entry (brentq would then find a root that
    is not the first one). Returns absolute collision times, contacts, states after."""
    M = MASS
    inertia = M * ell * ell if inertia is None else inertia
    events = [_make_gap(R, ell, +1), _make_gap(R, ell, -1)]
    q = np.array(q0, dtype=float)
    t0 = 0.0
    ts, ks, qs = np.empty(n), np.empty(n, dtype=int), np.empty((n, 6))
    nsteps = 0
    for i in range(n):
        speed = math.hypot(q[3], q[4]) + ell * abs(q[5])
        horizon = 100.0 * (2.0 * R) / speed  # far beyond any free flight
        sol = solve_ivp(
            _rhs,
            (t0, t0 + horizon),
            q,
            method="DOP853",
            rtol=rtol,
            atol=atol,
            events=events,
            max_step=step_frac * R / speed,
        )
        nsteps += sol.t.size - 1
        if sol.status != 1:
            raise RuntimeError(f"scipy loop: no collision found at collision {i}")
        hits = [(te[0], j) for j, te in enumerate(sol.t_events) if te.size]
        te, j = min(hits)
        k = (+1, -1)[j]
        qe = sol.y_events[j][0]
        q = impulse(qe, k, R, ell, M, inertia)
        t0 = te
        ts[i], ks[i], qs[i] = te, k, q
    return ts, ks, qs, nsteps


def time_scipy(R, ell, inertia, q0, n, repeats):
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        _, _, _, nsteps = scipy_orbit(R, ell, inertia, q0, n)
        times.append(time.perf_counter() - t)
    return statistics.median(times), nsteps / n


# --------------------------------------------------------------------------------------
# jaxbill side
# --------------------------------------------------------------------------------------
def nice(n):
    """Round n to 1, 2 or 5 times a power of ten (at least 1)."""
    n = max(1.0, float(n))
    p = 10.0 ** math.floor(math.log10(n))
    for m in (1, 2, 5, 10):
        if n <= m * p * 1.5:
            return int(m * p)
    return int(10 * p)


def _timed_call(jb, jax, scene, x, n):
    t = time.perf_counter()
    out = jax.block_until_ready(jb.orbit(scene, x, n))
    return time.perf_counter() - t, out


def time_jaxbill(jb, jax, scene, x, n, repeats):
    """First call (compile + run) and `repeats` steady-state runs of jb.orbit(scene, x, n).
    JAX caches are cleared first so that the first call really compiles."""
    jax.clear_caches()
    first, out = _timed_call(jb, jax, scene, x, n)
    runs = [_timed_call(jb, jax, scene, x, n)[0] for _ in range(repeats)]
    bad = int(np.sum(np.asarray(out.contact)[..., -1] == 0))  # NaN-poisoned or no contact
    return first, runs, bad


def bench_scene_batch(
    jb, jax, scene, x, repeats, n_fixed=None, target_s=1.0, pilot_collisions=100_000, max_collisions=20_000_000
):
    """Time jb.orbit on the batch x. Unless n_fixed is given, a pilot run (small n)
    measures the rate and n is chosen so that one steady run takes ~target_s."""
    B = 1 if x.ndim == 1 else x.shape[0]
    pilot = None
    if n_fixed is None:
        n_p = nice(max(1, pilot_collisions // B))
        first_p, runs_p, _ = time_jaxbill(jb, jax, scene, x, n_p, 1)
        rate_p = B * n_p / runs_p[0]
        n = nice(min(target_s * rate_p, max_collisions) / B)
        pilot = dict(n=n_p, first=first_p, rate=rate_p)
    else:
        n = n_fixed
    first, runs, bad = time_jaxbill(jb, jax, scene, x, n, repeats)
    med = statistics.median(runs)
    return dict(B=B, n=n, first=first, runs=runs, med=med, compile=first - med, rate=B * n / med, pilot=pilot, bad=bad)


def R_ell(scene):
    return float(scene.R), float(scene.ell)


def exact_flight_errors(r_ell, prev, ks, dt_scipy, dt_jaxbill, digits=40):
    """Max abs error of both flight-time series against the root of the gap of the
    contact end computed with mpmath at `digits` digits (None if mpmath is missing)."""
    try:
        import mpmath as mp
    except ImportError:
        return None, None
    R, ell = r_ell
    es, ej = [], []
    with mp.workdps(digits):
        for q, k, ds, dj in zip(prev, ks, dt_scipy, dt_jaxbill):
            x, y, a, vx, vy, om = (mp.mpf(float(v)) for v in q)

            def gap(t):
                px = x + vx * t + int(k) * ell * mp.cos(a + om * t)
                py = y + vy * t + int(k) * ell * mp.sin(a + om * t)
                return R * R - (px * px + py * py)

            root = mp.findroot(gap, mp.mpf(float(ds)))
            es.append(float(abs(ds - root)))
            ej.append(float(abs(dj - root)))
    return max(es), max(ej)


def accuracy_vs_jaxbill(jb, jax, jnp, scene, q0, ts, ks, qs, tol=1e-9):
    """Compare the scipy loop with jaxbill on the same initial state.

    per flight: jb.collide restarted from every scipy post-collision state, flight time
    and contact compared with scipy's (no chaotic amplification). orbit: absolute
    collision times of jb.orbit and of scipy over the first 10 collisions, and the
    number of leading collisions on which they agree to `tol` (beyond it the two
    orbits part at the rate of the Lyapunov exponent)."""
    n = len(ts)
    orb = jb.orbit(scene, jnp.asarray(q0), n)
    tj, kj = np.asarray(orb.t), np.asarray(orb.contact)
    prev = np.concatenate([q0[None], qs[:-1]], axis=0)
    _, dtj, kc = jax.vmap(lambda s: jb.collide(scene, s))(jnp.asarray(prev))
    dts = np.diff(np.concatenate([[0.0], ts]))
    dt_orbit = np.abs(tj - ts)
    off = np.nonzero(~(dt_orbit <= tol) | (kj != ks))[0]
    err_s, err_j = exact_flight_errors(R_ell(scene), prev, ks, dts, np.asarray(dtj))
    return dict(
        err_scipy=err_s,
        err_jaxbill=err_j,
        flight=float(np.max(np.abs(np.asarray(dtj) - dts))),
        flight_contact_mismatch=int(np.sum(np.asarray(kc) != ks)),
        traj10=float(np.max(dt_orbit[:10])),
        agree=int(off[0]) if off.size else n,
    )


def fmt_rate(r):
    return f"{r:.3g}"


def fmt_e(x):
    return "n/a" if x is None else f"{x:.1e}"


def machine_info(jax):
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next((l.split(":", 1)[1].strip() for l in f if l.startswith("model name")), "?")
    except OSError:
        cpu = platform.processor() or "?"
    try:
        avail = len(os.sched_getaffinity(0))
    except AttributeError:
        avail = os.cpu_count()
    devs = jax.devices()
    lines = [
        "## Machine",
        "",
        f"- python {platform.python_version()}, numpy {np.__version__}, scipy {__import__('scipy').__version__}",
        f"- jax {jax.__version__}, jaxlib {__import__('jaxlib').__version__}, "
        f"backend {jax.default_backend()}, devices {[str(d) for d in devs]}",
        f"- device kind: {devs[0].device_kind}",
        f"- CPU: {cpu}; os.cpu_count() = {os.cpu_count()}, usable cores = {avail}",
        f"- platform: {platform.platform()}",
        f"- jax_enable_x64 = {jax.config.read('jax_enable_x64')}, XLA_FLAGS = {os.environ.get('XLA_FLAGS', '')!r}",
    ]
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="fast smoke version (< 1 min)")
    ap.add_argument(
        "--repeats", type=int, default=None, help="timed steady-state runs per configuration (default 5, quick 2)"
    )
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    quick = args.quick
    repeats = max(1, args.repeats or (2 if quick else 5))
    # quick: fixed small n (no pilot); full: pilot, then n for ~1 s per run
    quick_n = {1: 5000, 1024: 20, 16384: 2}
    scipy_n, scipy_rep, acc_n = (60, 1, 40) if quick else (400, 3, 40)

    import jax
    import jax.numpy as jnp

    import jaxbill as jb  # enables float64

    print("# jaxbill collision benchmark" + (" (--quick: small n, timings are noisy)" if quick else ""))
    print()
    print(machine_info(jax))
    load0 = os.getloadavg()
    print(
        f"- load average at start (1/5/15 min): {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}"
        " (other processes on the cores make every number below smaller)"
    )
    print()
    sys.stdout.flush()

    results = {}  # (scene label, B) -> dict
    scipy_res = {}
    t_all = time.perf_counter()

    def progress(msg):
        print(f"  [{time.perf_counter() - t_all:6.1f}s] {msg}", file=sys.stderr, flush=True)

    for si, (label, R, ell, inertia) in enumerate(SCENES):
        scene = jb.StickInCircle(R=R, ell=ell, mass=MASS, inertia=inertia)
        for B in BATCHES:
            states0 = random_states(R, ell, inertia, B, seed=args.seed + 1000 * si + B)
            x = jnp.asarray(states0[0] if B == 1 else states0)
            r = bench_scene_batch(jb, jax, scene, x, repeats, n_fixed=quick_n[B] if quick else None)
            results[label, B] = r
            progress(
                f"{label:24s} B={B:<6d} n={r['n']:<7d} compile {r['compile']:.2f}s, "
                f"steady {r['med']:.3f}s, {fmt_rate(r['rate'])} coll/s"
            )
        # scipy loop on one orbit, from the same initial state as jaxbill's B = 1 run
        q0 = random_states(R, ell, inertia, 1, seed=args.seed + 1000 * si + 1)[0]
        ts, ks, qs, _ = scipy_orbit(R, ell, inertia, q0, acc_n)
        acc = accuracy_vs_jaxbill(jb, jax, jnp, scene, q0, ts, ks, qs)
        med, steps = time_scipy(R, ell, inertia, q0, scipy_n, scipy_rep)
        scipy_res[label] = dict(acc=acc, rate=scipy_n / med, steps=steps)
        progress(f"{label:24s} scipy {fmt_rate(scipy_n / med)} coll/s")
    wall = time.perf_counter() - t_all
    load1 = os.getloadavg()

    # ---------------- tables ----------------
    print("## jb.orbit throughput (float64)")
    print()
    print(
        f"Steady state = median of {repeats} runs after the first (compiling) call; "
        "compile = first call - steady median (JAX caches cleared before each first call). "
        "collisions/run = B * n; n chosen from a pilot run so that one run takes ~1 s"
        + (" (--quick: fixed small n)" if quick else "")
        + ". B = 1 passes state0 of "
        "shape (6,), B > 1 shape (B, 6). 'stalled' = orbits whose last contact is 0 "
        "(no collision found, or NaN-poisoned by the library)."
    )
    print()
    print(
        "| scene | B | n per orbit | collisions/run | compile (s) | steady median (s) "
        "| min-max (s) | stalled | collisions/s |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for label, *_ in SCENES:
        for B in BATCHES:
            r = results[label, B]
            print(
                f"| {label} | {B} | {r['n']} | {B * r['n']:.3g} | {r['compile']:.2f} | "
                f"{r['med']:.3f} | {min(r['runs']):.3f}-{max(r['runs']):.3f} | {r['bad']} | "
                f"**{fmt_rate(r['rate'])}** |"
            )
    print()
    print("## scipy solve_ivp loop, one orbit")
    print()
    print(
        "DOP853, rtol = atol = 1e-12, events g_k = R^2 - |P_k|^2 (terminal, direction -1), "
        "max_step = 0.1 R / (|v| + ell |omega|) so no step jumps over an exit and re-entry; "
        "impulse applied at each event, then restart. Same initial state as jaxbill's B = 1 "
        f"run. Accuracy over the first {acc_n} collisions: 'per flight' restarts jb.collide "
        "from each scipy post-collision state and compares the flight time (and contact "
        "end); 'dt error' is each side's flight time minus the contact end's gap root "
        "found with mpmath at 40 digits from the same scipy state; 'orbit' compares the "
        "absolute collision times of jb.orbit and scipy, which part at the Lyapunov rate, "
        "so it says for how many collisions they agree to 1e-9. "
        f"Speed: median of {scipy_rep} run(s) of {scipy_n} collisions."
    )
    print()
    print(
        "| scene | per flight: max abs dt error, scipy | same, jaxbill "
        "| per flight: max abs dt diff | contact mismatches | orbit: max abs t diff, "
        "first 10 | orbit: collisions agreeing to 1e-9 | solver steps/collision "
        "| scipy coll/s | jaxbill B=1 / scipy | jaxbill best batch / scipy |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for label, *_ in SCENES:
        sr = scipy_res[label]
        a = sr["acc"]
        single = results[label, 1]["rate"]
        best = max(results[label, B]["rate"] for B in BATCHES)
        print(
            f"| {label} | {fmt_e(a['err_scipy'])} | {fmt_e(a['err_jaxbill'])} "
            f"| {fmt_e(a['flight'])} | {a['flight_contact_mismatch']} | "
            f"{fmt_e(a['traj10'])} | {a['agree']} of {acc_n} | {sr['steps']:.1f} | "
            f"{fmt_rate(sr['rate'])} | {single / sr['rate']:.0f}x | {best / sr['rate']:.0f}x |"
        )
    print()
    print("## Targets")
    print()
    print("| target | scene | measured | met |")
    print("|---|---|---:|:---:|")

    def row(name, label, value, target, unit=""):
        ok = "yes" if value >= target else "**NO**"
        print(f"| {name} | {label} | {fmt_rate(value)}{unit} | {ok} |")

    for label, _, ell, inertia in SCENES:
        if inertia is None and ell == 1.9:
            row(
                f">= {TARGET_ROTOR_BATCH:.0e} coll/s, B=16384", label, results[label, 16384]["rate"], TARGET_ROTOR_BATCH
            )
    for label, _, _, inertia in SCENES:
        if inertia is not None:
            row(f">= {TARGET_LENS_BATCH:.0e} coll/s, B=16384", label, results[label, 16384]["rate"], TARGET_LENS_BATCH)
    for label, *_ in SCENES:
        row(f">= {TARGET_SINGLE:.0e} coll/s, single orbit", label, results[label, 1]["rate"], TARGET_SINGLE)
    for label, *_ in SCENES:
        row(
            f">= {TARGET_SCIPY_RATIO:.0f}x scipy loop, single orbit",
            label,
            results[label, 1]["rate"] / scipy_res[label]["rate"],
            TARGET_SCIPY_RATIO,
            "x",
        )
    for label, *_ in SCENES:
        best = max(results[label, B]["rate"] for B in BATCHES)
        row(
            f">= {TARGET_SCIPY_RATIO:.0f}x scipy loop, best batch",
            label,
            best / scipy_res[label]["rate"],
            TARGET_SCIPY_RATIO,
            "x",
        )
    print()
    print(
        f"Benchmark wall time {wall:.0f} s; load average at end (1/5/15 min): "
        f"{load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}."
    )


if __name__ == "__main__":
    main()
