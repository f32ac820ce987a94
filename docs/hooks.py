"""MkDocs hooks: the API reference, generated from ``jaxbill.__all__``, and the checks behind ``--strict``.

Every public name (``jaxbill.__all__`` and the ``jaxbill.plotting`` module)
gets a ``::: name`` block, rendered by mkdocstrings from its docstring, on one
of the pages of ``API_PAGES``; a name no page lists lands on "More" instead
of being left out. A public class or function without a docstring of its
own, or a constant without an entry in ``CONSTANTS``, is logged as a warning,
which ``mkdocs build --strict`` turns into a failed build.
"""

from __future__ import annotations

import inspect
import logging
import pathlib
import sys

from mkdocs.structure.files import File

log = logging.getLogger("mkdocs.hooks.jaxbill")
# Document the jaxbill beside this folder, whatever else is installed.
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent.parent))

# page: (title, what it holds, public names in the order shown)
API_PAGES = {
    "api/scenes.md": (
        "Scenes",
        "The scenes: their parameters, state layouts and contact codes.",
        ["StickInCircle", "StickInEllipse", "StickBetweenWalls2D", "StickBetweenWalls3D"],
    ),
    "api/orbits.md": (
        "Orbits and invariants",
        "The collision map, orbits and the quantities they conserve.",
        ["collide", "orbit", "Orbit", "energy", "angular_momentum", "end_points"],
    ),
    "api/runs.md": (
        "Long runs and devices",
        "Runs of any length, records on disk, resumes, every device.",
        ["run", "Run", "Section", "SectionPoints", "Checkpoint", "RunInterrupted", "orbit_sharded", "orbit_mesh"],
    ),
    "api/sections.md": (
        "Sections",
        "Section coordinates, their inverses and seeds, and measures on sections.",
        [
            "reduced_section",
            "section_state",
            "section_seeds",
            "reduced_section_bounds",
            "paper_section",
            "birkhoff_section",
            "incoming_states",
            "wall_length",
            "floor_section",
            "floor_state",
            "floor_seeds",
            "floor_section_bound",
            "reduced_wall_section",
            "theta_z_path",
            "wall_twin_divergence",
            "curve_thickness",
            "covered_fraction",
            "count_islands",
            "twin_divergence",
            "is_chaotic",
        ],
    ),
    "api/derivatives.md": (
        "Derivatives, Lyapunov spectra, chaos",
        "Tangent maps by autodiff and what is built on them.",
        [
            "tangent_map",
            "dynamical_indices",
            "dynamical_frame",
            "phase_velocity",
            "lyapunov_spectrum",
            "LyapunovSpectrum",
            "sample_energy_shell",
            "finite_time_lyapunov",
            "FiniteTimeLyapunov",
            "chaotic_fraction",
            "chaos_threshold",
            "fli",
            "megno",
            "fli_map",
            "FastLyapunovIndicator",
            "Megno",
            "ensemble_lyapunov",
            "EnsembleLyapunov",
            "torus_frequencies",
            "TorusFrequencies",
            "resonances",
        ],
    ),
    "api/periodic.md": (
        "Periodic orbits",
        "Periodic and relative periodic orbits, their stability and families.",
        ["find_periodic_orbit", "find_periodic_orbits", "continue_periodic_orbit", "PeriodicOrbit", "STABILITY_LABELS"],
    ),
    "api/checker.md": (
        "Independent check",
        "The diffrax checker.",
        ["check", "CheckResult", "CheckReport", "CheckFlag"],
    ),
    "api/explorer.md": ("Explorer", "The interactive section explorer.", ["explore"]),
}
# Objects a page shows after its public names: what those names return or take, documented
# where they live (imported from there by a user who needs them).
EXTRA_BLOCKS = {
    "api/explorer.md": [
        "jaxbill._explorer.Explorer",
        "jaxbill._explorer.ClickedOrbit",
        "jaxbill._explorer.SectionChart",
        "jaxbill._explorer.register_section_chart",
    ],
}
MORE_PAGE = "api/more.md"
MODULE_PAGES = {"api/plotting.md": ("Plotting", "jaxbill.plotting")}

# Constants cannot carry docstrings: what each public one holds.
CONSTANTS = {
    "STABILITY_LABELS": "The labels `PeriodicOrbit.stability` takes, from the monodromy multipliers: "
    "`'elliptic'`, `'parabolic'`, `'hyperbolic'`, `'inverse hyperbolic'`.",
}


def _block(name: str, value) -> str:
    if name in CONSTANTS:
        return f"### `jaxbill.{name}`\n\n`{value!r}`\n\n{CONSTANTS[name]}\n"
    return f"::: jaxbill.{name}\n"


def _check_documented(name: str, value) -> None:
    if inspect.isclass(value) or callable(value):
        own = value.__dict__.get("__doc__") if inspect.isclass(value) else value.__doc__
        if not (own or "").strip():
            log.warning("jaxbill.%s has no docstring: the API reference would show nothing for it", name)
    elif name not in CONSTANTS:
        log.warning("jaxbill.%s is a public constant without an entry in docs/hooks.py CONSTANTS", name)


def api_pages() -> dict[str, str]:
    """The API reference's pages, ``{path under docs/: markdown}``."""
    import jaxbill

    public = list(jaxbill.__all__)
    listed = set()
    pages = {}
    for path, (title, intro, names) in API_PAGES.items():
        shown = [n for n in names if n in public]
        listed.update(shown)
        blocks = [_block(n, getattr(jaxbill, n)) for n in shown]
        blocks += [f"::: {target}\n" for target in EXTRA_BLOCKS.get(path, [])]
        pages[path] = f"# {title}\n\n{intro}\n\n" + "\n".join(blocks)
    rest = [n for n in public if n not in listed]
    pages[MORE_PAGE] = "# More\n\nPublic names not yet given a page of their own.\n\n" + (
        "\n".join(_block(n, getattr(jaxbill, n)) for n in rest) if rest else "None at the moment.\n"
    )
    for path, (title, module) in MODULE_PAGES.items():
        pages[path] = f"# {title}\n\n::: {module}\n"
    for name in public:
        _check_documented(name, getattr(jaxbill, name))
    return pages


def on_files(files, config):
    for path, content in api_pages().items():
        files.append(File.generated(config, path, content=content))
    return files
