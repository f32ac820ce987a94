"""The driver of ``jaxbill figures``: every group of figures in turn, the progress bar, and the summary."""

from __future__ import annotations

import dataclasses
import json
import os
import sys
import time

from matplotlib.figure import Figure

from jaxbill._figures.common import Settings
from jaxbill._figures.compositions import make_compositions_figures
from jaxbill._figures.ellipse import make_ellipse_figures
from jaxbill._figures.paper import make_paper_figures
from jaxbill._figures.walls import make_walls_figures

FILES = (
    "fig1_trajectory.png",
    "fig2_projected_section.png",
    "fig3_lens_section.png",
    "ell_scan.png",
    "inertia_scan.png",
    "fig2_reduced_vs_projected.png",
    "spiral_column.png",
    "summary.json",
    "summary.txt",
)


class Progress:
    """A minimal progress bar on stderr (no dependency): ``[####......] 3/8 label  12.3 s``."""

    def __init__(self, total: int, enabled: bool = True, stream=None):
        self.total, self.done, self.enabled = total, 0, enabled
        self.stream = sys.stderr if stream is None else stream
        self.start = time.perf_counter()
        self.tty = getattr(self.stream, "isatty", lambda: False)()

    def show(self, label: str) -> None:
        if not self.enabled:
            return
        width = 24
        filled = int(width * self.done / self.total)
        elapsed = time.perf_counter() - self.start
        line = f"[{'#' * filled}{'.' * (width - filled)}] {self.done}/{self.total} {label:<38} {elapsed:6.1f} s"
        if self.tty:
            self.stream.write("\r" + line)
            if self.done == self.total:
                self.stream.write("\n")
        else:
            self.stream.write(line + "\n")
        self.stream.flush()

    def advance(self, label: str) -> None:
        self.done += 1
        self.show(label)


def _studies_figures(out_dir: str, quick: bool, bar) -> list:
    """``small_stick_law.png`` and ``arnold_web.png`` from the studies' stored data (notebooks 09 and 10).

    Both are drawn from ``notebooks/data/`` (the measurements take minutes to
    tens of minutes: ``notebooks/data/make_*_data.py``); where a file is
    missing (an install without the repository's notebooks) the figure is
    skipped and the summary says so.
    """
    from jaxbill.studies import arnold_web, small_stick

    records = []
    for name, data_file, draw in (
        ("small_stick_law", small_stick.DATA_FILE, lambda: small_stick.small_stick_figure(out_dir)),
        ("arnold_web", arnold_web.DATA_PATH, lambda: arnold_web.arnold_web_figure(out_dir, quick=quick)),
    ):
        t0 = time.perf_counter()
        if data_file.exists():
            records.append({"name": name, "file": os.path.basename(str(draw())), "seconds": time.perf_counter() - t0})
        else:
            records.append({"name": name, "file": None, "skipped": f"no stored data at {data_file}"})
        bar.advance(name.replace("_", " "))
    return records


def make_figures(
    out_dir: str = "figures", *, quick: bool = False, progress: bool = True, settings: Settings | None = None
) -> dict:
    """Compute and write every figure and the summary into ``out_dir``; return the summary.

    Args:
        out_dir: folder to write into (created if missing).
        quick: small runs (for tests) instead of the full defaults.
        progress: show a progress bar on stderr.
        settings: override the run sizes (default ``Settings()`` or
            ``Settings.quick_settings()``).
    """
    if settings is None:
        settings = Settings.quick_settings() if quick else Settings()
    os.makedirs(out_dir, exist_ok=True)
    steps = 14
    bar = Progress(steps, progress)
    bar.show("starting (compiling the collision map)")
    started = time.perf_counter()

    def save(fig: Figure, name: str) -> str:
        path = os.path.join(out_dir, name)
        fig.savefig(path, dpi=settings.dpi)
        return name

    figures = make_paper_figures(settings, save, bar)
    walls_figures = make_walls_figures(settings, save, bar)
    ellipse_figures = make_ellipse_figures(settings, save, bar)
    compositions_figures = make_compositions_figures(settings, save, bar)
    studies_figures = _studies_figures(out_dir, settings.quick, bar)

    all_panels = [p for f in figures for p in f["panels"]]
    summary = {
        "jaxbill_figures": 1,
        "quick": settings.quick,
        "settings": dataclasses.asdict(settings),
        "total_seconds": time.perf_counter() - started,
        "worst_energy_drift": max(p["energy_drift"] for p in all_panels),
        "worst_angular_momentum_drift": max(
            p["angular_momentum_drift"] for p in all_panels if p["angular_momentum_drift"] is not None
        ),
        "total_collisions": sum(
            p["collisions"] for f in figures if f["name"] not in ("spiral_column", "fig2_reduced") for p in f["panels"]
        ),
        "figures": figures,
        "walls": walls_figures,
        "ellipse": ellipse_figures,
        "compositions": compositions_figures,
        "studies": studies_figures,
        "walls_worst_energy_drift": max((p["energy_drift"] for f in walls_figures for p in f["panels"]), default=None),
        "walls_worst_momentum_drift": max(
            (p["momentum_drift"] for f in walls_figures for p in f["panels"]), default=None
        ),
    }
    with open(os.path.join(out_dir, "summary.json"), "w") as handle:
        json.dump(summary, handle, indent=1)
    with open(os.path.join(out_dir, "summary.txt"), "w") as handle:
        handle.write(summary_text(summary))
    bar.advance("summary")
    return summary


def summary_text(summary: dict) -> str:
    """The human-readable ``summary.txt``."""
    lines = [
        f"jaxbill figures ({'quick' if summary['quick'] else 'full'} run): "
        f"{summary['total_collisions']} collisions in {summary['total_seconds']:.1f} s",
        f"worst relative energy drift {summary['worst_energy_drift']:.2e}; "
        f"worst angular-momentum drift {summary['worst_angular_momentum_drift']:.2e} (units of R sqrt(2 M E))",
        "",
        f"{'file':<31} {'panel':<26} {'inertia':>9} {'orbits':>6} {'coll/orbit':>10} "
        f"{'dE/E':>9} {'dL':>9} {'chaotic':>7}",
    ]
    for figure in summary["figures"]:
        for panel in figure["panels"]:
            inertia = panel["scene"]["inertia"]
            inertia = inertia if isinstance(inertia, str) else f"{inertia:.4g}"
            dl = panel["angular_momentum_drift"]
            chaotic = panel.get("chaotic_fraction")
            lines.append(
                f"{figure['file']:<31} {panel['label']:<26} {inertia:>9} {panel['orbits']:>6} "
                f"{panel['collisions_per_orbit']:>10} {panel['energy_drift']:>9.1e} "
                f"{'-' if dl is None else f'{dl:.1e}':>9} {'-' if chaotic is None else f'{chaotic:.2f}':>7}"
            )
    lines += [
        "",
        "Energy E = 1/2 and total angular momentum L = 0 for every section orbit; R = 2, mass 1.",
        "dE/E = max |E_j/E_0 - 1|; dL = max |L_j - L_0| / (R sqrt(2 M E_0)) (none for the lens: L not conserved).",
        "chaotic = share of orbits that part from a twin turned by 1e-11 rad by more than 1e-3 (tori: < 1e-6).",
        "",
    ]
    for figure in summary["figures"]:
        lines.append(f"{figure['file']}: {figure['description']} ({figure['seconds']:.1f} s)")
    if summary.get("walls"):
        lines += [
            "",
            "Stick between two flat walls: ell = 1, mass 1, I = M ell^2, E' = 1/2 (no horizontal motion).",
            f"{'file':<23} {'panel':<24} {'orbits':>6} {'coll/orbit':>10} {'floor':>7} {'flat':>5} "
            f"{'dE/E':>9} {'dP':>9} {'chaotic':>7} {'apart':>6} {'lyap':>6}",
        ]
        for figure in summary["walls"]:
            for panel in figure["panels"]:
                lyap = panel["lyapunov_per_collision"]
                lines.append(
                    f"{figure['file']:<23} {panel['label']:<24} {panel['orbits']:>6} "
                    f"{panel['collisions_per_orbit']:>10} "
                    f"{panel['floor_collisions']:>7} {panel['several_contacts']:>5} {panel['energy_drift']:>9.1e} "
                    f"{panel['momentum_drift']:>9.1e} {panel['chaotic_fraction']:>7.2f} "
                    f"{panel['median_separation_collisions']:>6.0f} {'-' if lyap is None else f'{lyap:.2f}':>6}"
                )
        lines += [
            "floor = floor collisions (section points); flat = contacts 2 (flat landings, kinks); "
            "dP = max drift of M vx (2D) or L_z (3D) in units of sqrt(2 M E') or sqrt(2 I E');",
            "chaotic = share of orbits that part from a twin ((theta_dot, eta_dot) turned by 1e-11 rad) by "
            "more than 1e-3; apart = median collisions until 1e-4 apart; lyap = median ln(1e7)/apart "
            "of the chaotic ones (per collision).",
            "",
        ]
        for figure in summary["walls"]:
            lines.append(f"{figure['file']}: {figure['description']} ({figure['seconds']:.1f} s)")
    for figure in summary.get("ellipse", []):
        lines += ["", f"{figure['file']}: {figure['description']} ({figure['seconds']:.1f} s)"]
        for panel in figure["panels"]:
            lines.append(
                f"  {panel['label']:<34} {panel['orbits']:>4} orbits x {panel['collisions_per_orbit']} "
                f"collisions, dE/E {panel['energy_drift']:.1e}"
            )
    for figure in summary.get("compositions", []):
        lines += ["", f"{figure['file']}: {figure['description']} ({figure['seconds']:.1f} s)"]
        for panel in figure["panels"]:
            lines.append(
                f"  {panel['label']:<28} {panel['body']} in {panel['table']}: {panel['collisions']} collisions, "
                f"dE/E {panel['energy_drift']:.1e}"
            )
    for figure in summary.get("studies", []):
        if figure["file"] is None:
            lines += ["", f"{figure['name']}: skipped ({figure['skipped']})"]
        else:
            lines += ["", f"{figure['file']}: drawn from the stored measurement ({figure['seconds']:.1f} s)"]
    return "\n".join(lines) + "\n"
