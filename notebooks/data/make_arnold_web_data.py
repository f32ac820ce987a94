"""Compute the stored data of notebook 10 (the Arnold web of a stick in a slightly eccentric ellipse).

Writes ``notebooks/data/arnold_web.npz`` (about 2 MB):

1. circle frequencies ``nu1, nu2`` (``jaxbill.studies.arnold_web.torus_frequencies``)
   on a grid of ``(p on the line s = Lw/4) x L``;
2. FLI maps of the ellipse ``a = R (1 + eps)``, ``b = R (1 - eps)`` on that grid for
   ``eps = 0, 1e-4, 1e-3, 1e-2``;
3. fine one-dimensional FLI scans along ``L`` at fixed ``p`` for more ``eps``
   (the width of the main resonance against ``eps``);
4. ensembles run long through ``jb.run`` (``record="states"``), their
   ``<(L - L0)^2>`` at common times with error bars from sub-ensembles, and one
   orbit's path in ``(p*, L)``.

Run from the repository root, pinned to one core on a shared machine::

    taskset -c 0 python notebooks/data/make_arnold_web_data.py          # full size, ~20 min
    taskset -c 0 python notebooks/data/make_arnold_web_data.py --quick  # smoke test, ~1 min, writes /tmp

Sizes and the measured run time are stored in the file (``meta_*`` keys).
"""

from __future__ import annotations

import argparse
import json
import pathlib
import time

import numpy as np

import jaxbill as jb
from jaxbill.studies import arnold_web as aw

R, ELL, ENERGY = 2.0, 1.9, 0.5
MAP_EPS = (0.0, 1e-4, 1e-3, 1e-2)
SCAN_EPS = (1e-5, 3e-5, 1e-4, 3e-4, 1e-3, 3e-3, 1e-2)
DIFF_EPS = (0.0, 1e-4, 3e-4, 1e-3, 3e-3, 1e-2)
SCAN_P = 0.3


def sizes(quick: bool) -> dict:
    if quick:
        return dict(
            nx=40,
            ny=40,
            n_map=500,
            n_freq=1000,
            n_scan_L=200,
            n_scan=1000,
            batch=16,
            n_diff_fast=4000,
            n_diff_slow=8000,
            every=50,
            n_times=20,
            n_path=4000,
            path_window=40,
        )
    return dict(
        nx=200,
        ny=200,
        n_map=2000,
        n_freq=2000,
        n_scan_L=1200,
        n_scan=4000,
        batch=64,
        n_diff_fast=200_000,
        n_diff_slow=1_000_000,
        every=250,
        n_times=40,
        n_path=100_000,
        path_window=100,
    )


def main(quick: bool, out: pathlib.Path) -> None:
    t_start = time.time()
    cfg = sizes(quick)
    circle = aw.circle_scene(R, ELL)
    data: dict = {}
    timing: dict = {}

    # ---------------------------------------------------------------- grid and circle frequencies
    p = np.linspace(-1.0, 1.0, cfg["nx"])
    L = np.linspace(-2.0, 2.0, cfg["ny"])
    grid = aw.web_grid(circle, p, L, ENERGY)
    t0 = time.time()
    freq = aw.torus_frequencies(circle, grid, cfg["n_freq"])
    timing["frequencies"] = time.time() - t0
    data.update(p=p, L=L, nu1=freq.nu1, nu2=freq.nu2, spread=freq.spread)
    print(f"frequencies: {timing['frequencies']:.0f} s", flush=True)

    # ---------------------------------------------------------------- FLI maps
    for eps in MAP_EPS:
        t0 = time.time()
        fli = jb.fli_map(aw.ellipse_scene(R, ELL, eps), grid, cfg["n_map"])
        timing[f"map_{eps:g}"] = time.time() - t0
        data[f"fli_{eps:g}"] = fli.astype(np.float32)
        print(f"map eps={eps:g}: {timing[f'map_{eps:g}']:.0f} s", flush=True)

    # ---------------------------------------------------------------- fine scans along L at p = SCAN_P
    scan_L = np.linspace(-1.6, 1.6, cfg["n_scan_L"])
    column = aw.web_grid(circle, np.array([SCAN_P]), scan_L, ENERGY)
    sf = aw.torus_frequencies(circle, column, cfg["n_freq"])
    data.update(scan_L=scan_L, scan_nu1=sf.nu1[:, 0], scan_nu2=sf.nu2[:, 0], scan_spread=sf.spread[:, 0])
    t0 = time.time()
    scans = np.stack([jb.fli_map(aw.ellipse_scene(R, ELL, eps), column, cfg["n_scan"])[:, 0] for eps in SCAN_EPS])
    timing["scans"] = time.time() - t0
    data.update(scan_eps=np.array(SCAN_EPS), scan_fli=scans.astype(np.float32))
    print(f"scans: {timing['scans']:.0f} s", flush=True)

    # the edges of the main resonance (0, 2, 0) in each scan: the ridges nearest L_res on each side
    l_res = aw.resonance_crossings((0, 2, 0), scan_L, sf.nu1, sf.nu2, valid=sf.spread < 1e-8, axis=0)[0]
    l_res = float(l_res[np.argmin(np.abs(l_res))]) if len(l_res) else np.nan
    edges = []
    for fli in scans:
        r = aw.fli_ridges(fli[:, None], scan_L, contrast=0.5, width=3, axis=0)[0]
        o = aw.ridge_offsets([r], [[l_res]], window=1.5)
        edges.append((o.below[0], o.above[0]))
    data.update(scan_resonance_L=l_res, scan_edges=np.array(edges))

    # ---------------------------------------------------------------- diffusion of L
    rng = np.random.default_rng(20)
    B = cfg["batch"]
    fli0 = data["fli_0"]
    ll = np.broadcast_to(L[:, None], freq.spread.shape)
    # (a) the circle's own chaotic layer at the edge of its regular region, at L near 0.5
    rim = np.flatnonzero(
        ((freq.spread > 1e-4) & (np.abs(ll - 0.5) < (0.1 if not quick else 0.3)) & np.isfinite(fli0)).ravel()
    )
    rim_starts = grid.reshape(-1, 6)[rng.choice(rim, B, replace=rim.size < B)]
    # (c) regular tori of the circle, well inside the regular region
    tor_starts = aw.web_starts(circle, 0.5 + 0.04 * (rng.random(B) - 0.5), 0.8 + 0.04 * (rng.random(B) - 0.5), ENERGY)

    def separatrix_starts(eps):
        # (b) the upper edge of the (0, 2, 0) band (its chaotic layer) from the scan at this eps
        i = SCAN_EPS.index(eps) if eps in SCAN_EPS else SCAN_EPS.index(1e-3)
        l_edge = l_res + edges[i][1]
        ls = l_edge + 2e-3 * (rng.random(B) - 0.5)
        ps = SCAN_P + 1e-2 * (rng.random(B) - 0.5)
        return aw.web_starts(circle, ps, ls, ENERGY), l_edge

    ensembles = {}
    total_collisions = 0
    t0 = time.time()
    for eps in DIFF_EPS:
        scene = aw.ellipse_scene(R, ELL, eps)
        n = cfg["n_diff_slow"] if 0.0 < eps < 1e-3 else cfg["n_diff_fast"]
        sep_starts, l_edge = separatrix_starts(eps)
        for name, starts in (("rim", rim_starts), ("separatrix", sep_starts), ("torus", tor_starts)):
            t1 = time.time()
            run = jb.run(scene, starts, n, record="states", every=cfg["every"], progress=False)
            L_rec = np.asarray(jb.angular_momentum(scene, run.state))
            L0 = np.asarray(jb.angular_momentum(scene, starts))
            t_rec = np.asarray(run.t)
            ensembles[(name, eps)] = dict(
                t=t_rec,
                L=L_rec,
                L0=L0,
                t_end=float(t_rec[:, -1].min()),
                wall=time.time() - t1,
                n=n,
                max_dL=float(np.max(np.abs(L_rec - L0[:, None]))),
            )
            total_collisions += B * n
            print(
                f"diffusion {name} eps={eps:g}: n={n} {time.time() - t1:.0f} s "
                f"max|dL|={ensembles[(name, eps)]['max_dL']:.3g}",
                flush=True,
            )
    timing["diffusion"] = time.time() - t0

    # common time windows per eps (every ensemble of one eps on the same times)
    names = ("rim", "separatrix", "torus")
    n_t = cfg["n_times"]
    times = np.zeros((len(DIFF_EPS), n_t))
    msd = np.zeros((len(names), len(DIFF_EPS), n_t))
    err = np.zeros_like(msd)
    max_dl = np.zeros((len(names), len(DIFF_EPS)))
    l0_mean = np.zeros((len(names), len(DIFF_EPS)))
    for j, eps in enumerate(DIFF_EPS):
        t_end = min(ensembles[(nm, eps)]["t_end"] for nm in names)
        t_first = max(float(ensembles[(nm, eps)]["t"][:, 0].max()) for nm in names)
        times[j] = np.geomspace(max(t_end * 1e-4, t_first), t_end, n_t)
        for i, nm in enumerate(names):
            e = ensembles[(nm, eps)]
            msd[i, j], err[i, j] = aw.spread_against_time(e["t"], e["L"], e["L0"], times[j], n_sub=8)
            max_dl[i, j] = e["max_dL"]
            l0_mean[i, j] = float(np.mean(e["L0"]))
    data.update(
        diff_eps=np.array(DIFF_EPS),
        diff_names=np.array(names),
        diff_times=times,
        diff_msd=msd,
        diff_err=err,
        diff_max_dL=max_dl,
        diff_L0=l0_mean,
        diff_collisions=np.array([[ensembles[(nm, eps)]["n"] for eps in DIFF_EPS] for nm in names]),
    )

    # ---------------------------------------------------------------- one diffusing orbit's path in (p*, L)
    path_eps = 1e-3
    i_best = int(np.argmax(np.abs(ensembles[("rim", path_eps)]["L"][:, -1] - ensembles[("rim", path_eps)]["L0"])))
    start = rim_starts[i_best]
    t0 = time.time()
    orb = jb.run(aw.ellipse_scene(R, ELL, path_eps), start, cfg["n_path"], record="states", progress=False)
    p_star, l_path = aw.torus_label_path(circle, np.asarray(orb.state), cfg["path_window"])
    timing["path"] = time.time() - t0
    data.update(
        path_eps=path_eps,
        path_p=p_star.astype(np.float32),
        path_L=l_path.astype(np.float32),
        path_t=np.asarray(orb.t)[cfg["path_window"] - 1 :: cfg["path_window"]][: len(l_path)].astype(np.float32),
        path_start=start,
    )
    total_collisions += cfg["n_path"]

    timing["total"] = time.time() - t_start
    meta = dict(
        R=R,
        ell=ELL,
        energy=ENERGY,
        mass=1.0,
        inertia=ELL**2,
        quick=quick,
        sizes=cfg,
        timing_s=timing,
        diffusion_collisions_total=int(total_collisions),
        scan_p=SCAN_P,
        jaxbill=jb.__version__,
        note="FLI per collision, jb.fli_map default tangent; starts from aw.web_grid",
    )
    data["meta_json"] = json.dumps(meta)
    out.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(out, **data)
    print(f"wrote {out} ({out.stat().st_size / 1e6:.2f} MB) in {timing['total']:.0f} s", flush=True)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="small sizes, output in /tmp")
    parser.add_argument("--out", type=pathlib.Path, default=None)
    args = parser.parse_args()
    default = pathlib.Path("/tmp/arnold_web_quick.npz") if args.quick else aw.DATA_PATH
    main(args.quick, args.out or default)
