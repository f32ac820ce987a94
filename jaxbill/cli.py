"""The ``jaxbill`` console command."""

from __future__ import annotations

import argparse
import sys
import time

DEFAULT_DEMO_STATE = (0.05, 0.02, 0.4, 0.8, 0.5, 0.6)
# --scene of `jaxbill explore`: the scene each name opens (their parameters are the options below).
EXPLORE_SCENES = {
    "circle": "StickInCircle",
    "ellipse": "StickInEllipse",
    "walls2d": "StickBetweenWalls2D",
    "walls3d": "StickBetweenWalls3D",
}


def _demo(args: argparse.Namespace) -> int:
    import jax
    import jax.numpy as jnp
    import numpy as np

    import jaxbill as jb

    scene = jb.StickInCircle(R=args.R, ell=args.ell)
    state0 = jnp.asarray(DEFAULT_DEMO_STATE)
    print(
        f"jaxbill {jb.__version__} on {jax.devices()[0].platform}: "
        f"stick in a circle, R = {args.R}, ell = {args.ell}, mass = 1, inertia = mass ell^2"
    )
    print("state = [x, y, alpha, vx, vy, omega]; contact +1 = end P1 = c + ell u, -1 = end P2\n")
    start = time.perf_counter()
    orb = jax.block_until_ready(jb.orbit(scene, state0, args.n))
    elapsed = time.perf_counter() - start
    e0, l0 = jb.energy(scene, state0), jb.angular_momentum(scene, state0)
    print(f"{'k':>4} {'t':>10} {'contact':>7}  state just after the collision")
    for k in range(min(args.show, args.n)):
        s = np.asarray(orb.state[k])
        print(f"{k + 1:>4} {float(orb.t[k]):>10.6f} {int(orb.contact[k]):>7}  " + " ".join(f"{v:+.6f}" for v in s))
    energies = jb.energy(scene, orb.state)
    momenta = jb.angular_momentum(scene, orb.state)
    print(f"\n{args.n} collisions in {elapsed:.2f} s (compilation included)")
    print(f"energy E = {float(e0):.15f}, worst relative drift {float(jnp.max(jnp.abs(energies / e0 - 1))):.2e}")
    print(f"angular momentum L = {float(l0):.15f}, worst drift {float(jnp.max(jnp.abs(momenta - l0))):.2e}")
    return 0


def _figures(args: argparse.Namespace) -> int:
    from jaxbill._figures import make_figures

    summary = make_figures(args.out, quick=args.quick, progress=not args.no_progress)
    drawn = summary.get("walls", []) + summary.get("ellipse", []) + summary.get("compositions", [])
    drawn += [figure for figure in summary.get("studies", []) if figure["file"] is not None]
    figures = len(summary["figures"]) + len(drawn)
    print(
        f"wrote {figures} figures, summary.json and summary.txt to {args.out} "
        f"in {summary['total_seconds']:.1f} s ({summary['total_collisions']} collisions; worst relative "
        f"energy drift {summary['worst_energy_drift']:.1e})"
    )
    return 0


def _explore_scene(args: argparse.Namespace):
    import jaxbill as jb

    if args.scene == "circle":
        ell = 1.2 if args.ell is None else args.ell
        return jb.StickInCircle(R=args.R, ell=ell, inertia=args.inertia)
    if args.scene == "ellipse":
        ell = 0.5 if args.ell is None else args.ell
        return jb.StickInEllipse(a=args.a, b=args.b, ell=ell, inertia=args.inertia)
    ell = 1.0 if args.ell is None else args.ell
    walls = jb.StickBetweenWalls2D if args.scene == "walls2d" else jb.StickBetweenWalls3D
    return walls(h=args.h, ell=ell, inertia=args.inertia)


def _parse_point(text: str) -> tuple[float, float]:
    try:
        x, y = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected X,Y (two numbers); got {text!r}") from None
    return x, y


def _explore(args: argparse.Namespace) -> int:
    import matplotlib

    if args.save:
        matplotlib.use("Agg")  # no window: seed, click, save
    from jaxbill._explorer import explore, sample_clicks

    invariants = {
        name: value
        for name, value in (("energy", args.energy), ("angular_momentum", args.L), ("spin", args.spin))
        if value is not None
    }
    explorer = explore(_explore_scene(args), save_path=args.save or "jaxbill_explorer.png", **invariants)
    if not args.save:
        import matplotlib.pyplot as plt

        plt.show()
        return 0
    clicks = args.click or sample_clicks(explorer, args.clicks)
    for x, y in clicks:
        explorer.click(x, y)
        print(explorer.status)
    path = explorer.save(args.save)
    print(
        f"wrote {path}: {explorer.chart.title} of {type(explorer.scene).__name__} with "
        f"{len(explorer.orbits)} clicked orbits over a {explorer.survey_message}"
    )
    return 0


def _version() -> str:
    from jaxbill import __version__

    return __version__


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="jaxbill",
        description="Rigid-body billiards in JAX.",
        epilog="Run 'jaxbill COMMAND --help' for a command's options.",
    )
    parser.add_argument("--version", action="version", version=f"jaxbill {_version()}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")
    demo = commands.add_parser("demo", help="print the first collisions of a default orbit and its invariants")
    demo.add_argument("--R", type=float, default=2.0, help="circle radius (default 2)")
    demo.add_argument("--ell", type=float, default=1.9, help="stick half-length (default 1.9, the paper's Fig. 2)")
    demo.add_argument("-n", type=int, default=10000, help="number of collisions (default 10000)")
    demo.add_argument("--show", type=int, default=10, help="collisions to print (default 10)")
    demo.set_defaults(run=_demo)
    figures = commands.add_parser(
        "figures",
        help="reproduce the paper's figures, its parameter scans and the reduced section (PNGs and a summary)",
    )
    figures.add_argument("--out", default="figures", help="folder to write into (default ./figures)")
    figures.add_argument("--quick", action="store_true", help="a small, fast version (for tests)")
    figures.add_argument("--no-progress", action="store_true", help="no progress bar")
    figures.set_defaults(run=_figures)
    explore = commands.add_parser(
        "explore",
        help="an interactive section explorer: click on the section to start an orbit, sliders for the parameters",
    )
    explore.add_argument(
        "--scene",
        choices=tuple(EXPLORE_SCENES),
        default="circle",
        help=", ".join(f"{name}: {scene}" for name, scene in EXPLORE_SCENES.items()) + " (default circle)",
    )
    explore.add_argument("--R", type=float, default=2.0, help="circle radius (default 2)")
    explore.add_argument("--a", type=float, default=2.0, help="the ellipse's semi-axis along x (default 2)")
    explore.add_argument("--b", type=float, default=1.4, help="the ellipse's semi-axis along y (default 1.4)")
    explore.add_argument("--h", type=float, default=3.0, help="distance between the walls (default 3)")
    explore.add_argument(
        "--ell",
        type=float,
        default=None,
        help="stick half-length (default 1.2 in the circle, 0.5 in the ellipse, 1 between walls)",
    )
    explore.add_argument(
        "--inertia", type=float, default=None, help="moment of inertia (default mass ell^2; inf: the static lens)"
    )
    explore.add_argument("--energy", type=float, default=None, help="the section's energy E (E' for walls; 0.5)")
    explore.add_argument("--L", type=float, default=None, help="the circle's angular momentum L (default 0)")
    explore.add_argument("--spin", type=float, default=None, help="walls3d: I w_z (default 0.6 sqrt(I))")
    explore.add_argument(
        "--save",
        metavar="PATH",
        default=None,
        help="no window: seed the survey, click a few points, save a PNG to PATH",
    )
    explore.add_argument("--clicks", type=int, default=4, help="with --save: sample points to click (default 4)")
    explore.add_argument(
        "--click",
        type=_parse_point,
        action="append",
        metavar="X,Y",
        help="with --save: click this section point (repeatable; replaces --clicks)",
    )
    explore.set_defaults(run=_explore)
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help(sys.stderr)
        print("\njaxbill: error: choose a command (demo, figures or explore)", file=sys.stderr)
        return 2
    try:
        return args.run(args)
    except ValueError as error:
        print(f"jaxbill: error: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
