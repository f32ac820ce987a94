"""MkDocs hooks: the API reference from ``jaxbill.__all__``, the checks behind ``--strict``, the notebooks' maths.

Every public name (``jaxbill.__all__``, and the public modules ``jaxbill.plotting``
and ``jaxbill.studies``) gets a ``::: name`` block, rendered by mkdocstrings from
its docstring, on one of the pages of ``API_PAGES`` (``MODULE_PAGES``). A name no
page lists, a public class or function without a docstring of its own, or a
constant without an entry in ``CONSTANTS`` is logged as a warning, which
``mkdocs build --strict`` turns into a failed build. The scenes' pages leave out
what a scene implements for the engine (``ENGINE_MEMBERS``), documented once on
the page for adding a scene, and what a body or a table answers its scene
(``PART_MEMBERS``), documented with their bases on the page for extending.

Maths is typeset in the browser by the KaTeX bundled under ``docs/assets/``
(``docs/assets/render-maths.js``), from formulas marked ``\\( ... \\)`` or
``\\[ ... \\]`` inside an element of class ``arithmatex``: what
``pymdownx.arithmatex`` writes for the Markdown pages and the docstrings. The
notebooks' Markdown cells go through nbconvert instead, which would leave their
``$...$`` as typed; ``on_config`` makes it write the same marks, and
``on_page_content`` rebuilds each notebook's table of contents from its
rendered headings, so that the entries carry the headings' formulas and link
to the headings' own anchors (the table mkdocs-jupyter derives separately slugs
a heading with inline code differently from the heading itself).
"""

from __future__ import annotations

import html
import importlib
import inspect
import logging
import pathlib
import re
import sys

from mkdocs.structure.files import File
from mkdocs.structure.toc import get_toc

log = logging.getLogger("mkdocs.hooks.jaxbill")
# Document the jaxbill beside this folder, whatever else is installed.
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent.parent))

# page: (title, what it holds, public names in the order shown)
API_PAGES = {
    "api/scenes.md": (
        "Scenes",
        "The scenes: their parameters, state layouts, invariants and sections. What a scene "
        "answers the engine and the analyses (the root search, the impulse, the checks, the "
        "charts) is on the page for [adding a scene](../how-to/new-scene.md#4-the-protocols-member-by-member).",
        ["StickInCircle", "StickInEllipse", "StickBetweenWalls2D", "StickBetweenWalls3D"],
    ),
    "api/bodies.md": (
        "Bodies and tables",
        "A scene composed of any rigid body in any convex table, or a point in the field's standard tables that "
        "are not convex, `jb.BodyInTable(body, table)`: the scene, "
        "the bodies and the tables ([concepts](../concepts.md#compositions-a-body-in-a-table): the state "
        "layout, the gap numbering, the contact codes). What a body or a table answers the scene, and the "
        "walls tables are made of, are on the page for [extending](extending.md).",
        [
            "BodyInTable",
            "PointBody",
            "Dumbbell",
            "PolygonBody",
            "EllipseBody",
            "Circle",
            "Ellipse",
            "Stadium",
            "Polygon",
            "Strip",
            "ConvexTable",
            "Sinai",
            "LorentzGas",
            "Mushroom",
            "WithObstacles",
            "DiscObstacle",
            "EllipseObstacle",
        ],
    ),
    "api/extending.md": (
        "Extending: bodies, tables, walls",
        "The bases a new body or table subclasses, and the smooth walls (pieces) tables are made of, with "
        "every member the scene asks of them. Step by step, with the tests each needs: "
        "[a new table](../how-to/new-table.md), [a new body](../how-to/new-body.md).",
        [
            "Body",
            "Table",
            "Piece",
            "Motion",
            "DiscWall",
            "EllipseWall",
            "HalfPlane",
            "CapsuleWall",
            "FunctionWall",
            "Segment",
            "Arc",
            "PeriodicWall",
        ],
    ),
    "api/orbits.md": (
        "Orbits and invariants",
        "The collision map, orbits, what stopped them (result codes) and the quantities they conserve.",
        ["collide", "orbit", "Orbit", "Result", "energy", "angular_momentum", "end_points"],
    ),
    "api/runs.md": (
        "Long runs and devices",
        "Runs of any length, records on disk, resumes, every device, and the XLA settings made at import.",
        [
            "run",
            "Run",
            "Section",
            "SectionPoints",
            "Checkpoint",
            "RunInterrupted",
            "orbit_sharded",
            "orbit_mesh",
            "backend_settings",
        ],
    ),
    "api/sections.md": (
        "Sections",
        "Section coordinates, their inverses and seeds, measures on sections, and the twin test of chaos.",
        [
            "reduced_section",
            "section_state",
            "section_seeds",
            "reduced_section_bounds",
            "paper_section",
            "birkhoff_section",
            "incoming_states",
            "wall_length",
            "ellipse_length",
            "floor_section",
            "floor_state",
            "floor_seeds",
            "floor_section_bound",
            "reduced_wall_section",
            "theta_z_path",
            "curve_thickness",
            "covered_fraction",
            "count_islands",
            "twin_divergence",
            "is_chaotic",
            "orbits_with_twins",
            "CHAOTIC_DIVERGENCE",
            "wall_twin_divergence",
            "orbits_with_twin_distances",
            "separation_collisions",
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
# A public name on no page above lands here, and mkdocs warns (a failed --strict build)
# until it is listed on a page: the page is not in the navigation.
MORE_PAGE = "api/more.md"
# page: (title, what it holds, public modules in the order shown)
MODULE_PAGES = {
    "api/plotting.md": ("Plotting", "", ["jaxbill.plotting"]),
    "api/studies.md": (
        "Studies",
        "Two studies built on jaxbill, each with its stored data and its notebook "
        "([09](../notebooks/09_small_stick_chaos.ipynb), [10](../notebooks/10_arnold_web.ipynb)); "
        "import them by name, `from jaxbill.studies import small_stick, arnold_web`. "
        "What they share with the rest of the library (`ensemble_lyapunov`, `torus_frequencies`, "
        "`resonances`) is documented on the [derivatives](derivatives.md) page.",
        ["jaxbill.studies.small_stick", "jaxbill.studies.arnold_web"],
    ),
}

# Constants cannot carry docstrings: what each public one holds.
CONSTANTS = {
    "STABILITY_LABELS": "The labels `PeriodicOrbit.stability` takes, from the monodromy multipliers: "
    "`'elliptic'`, `'parabolic'`, `'hyperbolic'`, `'inverse hyperbolic'`.",
    "CHAOTIC_DIVERGENCE": "The `twin_divergence` above which an orbit counts as chaotic (`is_chaotic`): "
    "a torus keeps its twin within about `delta * n` (`1e-11` per collision), a chaotic orbit parts "
    "from it to order one.",
}

# What a scene implements for the engine and the analyses rather than for its user: kept
# off the scenes' page and documented once, with the protocols it answers, on the page for
# adding a scene (docs/how-to/new-scene.md). The Scene protocol's other members (gaps,
# approach speeds, energy, end points) are the user's too and stay.
ENGINE_MEMBERS = (
    # the Scene protocol: how a collision is computed, checked and batched
    "batch_chunk",
    "gap_scale",
    "check",
    "check_state_values",
    "is_valid",
    "motion_is_representable",
    "orbit_constants",
    "searches_for_roots",
    "root_search",
    "gaps_along_flight",
    "closed_form_contact",
    "collide_at",
    "contact_codes",
    "checks_curvature",
    "escape_code",
    "stop_condition",
    # the capabilities the analyses ask for (jb.explore, jb.check, jb.sample_energy_shell,
    # the tangent maps: the user calls those)
    "section_chart",
    "checker_flight",
    "sample_states",
    "dynamical_indices",
    "dynamical_size",
    "dynamical_frame",
    "phase_velocity",
    # the pieces the scenes build those from
    "kick",
    "inverse_inertia",
    "root_search_setup",
    "contact_gaps",
    "resolve_contact",
    "next_contact",
    "moved",
    "end_gaps",
    "end_approach_speeds",
    "end_gaps_and_speeds",
    "vertical_profile",
    # a composed scene's own steps of the collision (jaxbill._scenes.body_in_table)
    "flight_components",
    "contacts",
    "resolve",
    "contact_offsets_at",
    "clearances",
)
# What a body or a table answers its scene rather than its user: kept off the page of
# bodies and tables, documented with the bases (Body, Table) on the page for extending.
PART_MEMBERS = (
    "check",
    "parameters_are_valid",
    "offsets",
    "turn_vector",
    "inner_radius2",
    "mass_ratio",
    "energy",
    "spin_term",
    "outline",
    "turn_symmetry",
    "orientation_for",
    "supports",
    "contact_points",
    "gaps_along",
    "flight_bounds",
    "bounds_jerk",
    "quiet_interval",
    "exit_times",
    "has_closed_form",
    "gap_scale",
    "boundary_offset",
    "boundary_coordinate",
    "boundary_point",
    "clearance",
    "cell_origin",
    "cells_covering",
)
# The pages a user reads for the scenes themselves: the members above stay off them.
USER_SCENE_PAGES = ("api/scenes.md", "api/bodies.md")


def _hidden_members(value, page: str) -> tuple[str, ...]:
    """What a block on ``page`` leaves out: a body's or table's answers to its scene, a scene's to the engine."""
    if page not in USER_SCENE_PAGES or not inspect.isclass(value):
        return ()
    from jaxbill import Body, Table

    return PART_MEMBERS if issubclass(value, Body | Table) else ENGINE_MEMBERS


def _block(name: str, value, page: str = "") -> str:
    if name in CONSTANTS:
        return f"### `jaxbill.{name}`\n\n`{value!r}`\n\n{CONSTANTS[name]}\n"
    hidden = _hidden_members(value, page)
    if hidden:
        return f'::: jaxbill.{name}\n    options:\n      filters: ["!^_", "!^({"|".join(hidden)})$"]\n'
    return f"::: jaxbill.{name}\n"


def _check_documented(name: str, value) -> None:
    if inspect.isclass(value) or callable(value):
        own = value.__dict__.get("__doc__") if inspect.isclass(value) else value.__doc__
        if not (own or "").strip():
            log.warning("jaxbill.%s has no docstring: the API reference would show nothing for it", name)
    elif name not in CONSTANTS:
        log.warning("jaxbill.%s is a public constant without an entry in docs/hooks.py CONSTANTS", name)


def _module_block(module: str, public: list[str]) -> str:
    """A public module's block, leaving out what it shares with ``jaxbill.__all__`` (documented there)."""
    shared = sorted(set(getattr(importlib.import_module(module), "__all__", ())) & set(public))
    if not shared:
        return f"::: {module}\n"
    return f'::: {module}\n    options:\n      filters: ["!^_", "!^({"|".join(shared)})$"]\n'


def api_pages() -> dict[str, str]:
    """The API reference's pages, ``{path under docs/: markdown}``."""
    import jaxbill

    public = list(jaxbill.__all__)
    listed = set()
    pages = {}
    for path, (title, intro, names) in API_PAGES.items():
        shown = [n for n in names if n in public]
        listed.update(shown)
        blocks = [_block(n, getattr(jaxbill, n), path) for n in shown]
        blocks += [f"::: {target}\n" for target in EXTRA_BLOCKS.get(path, [])]
        pages[path] = f"# {title}\n\n{intro}\n\n" + "\n".join(blocks)
    rest = [n for n in public if n not in listed]
    if rest:
        log.warning("public names on no API page (list them in docs/hooks.py API_PAGES): %s", ", ".join(rest))
        pages[MORE_PAGE] = "# More\n\n" + "\n".join(_block(n, getattr(jaxbill, n)) for n in rest)
    for path, (title, intro, modules) in MODULE_PAGES.items():
        pages[path] = f"# {title}\n\n{intro}\n\n" + "\n".join(_module_block(m, public) for m in modules)
    for name in public:
        _check_documented(name, getattr(jaxbill, name))
    return pages


def on_files(files, config):
    for path, content in api_pages().items():
        files.append(File.generated(config, path, content=content))
    return files


# --------------------------------------------------------------------------- maths in the notebooks


def _mark_notebook_maths() -> None:
    """Have nbconvert write a notebook's formulas as ``pymdownx.arithmatex`` writes a page's.

    nbconvert's Markdown parser already tells formulas from text (``$...$``,
    ``$$...$$``, ``\\begin{env}``); only what its renderer writes for them changes.
    """
    from nbconvert.filters.markdown_mistune import IPythonRenderer

    def inline_math(self, body: str) -> str:
        return f'<span class="arithmatex">\\({self.escape_html(body)}\\)</span>'

    def block_math(self, body: str) -> str:
        return f'<span class="arithmatex">\\[{self.escape_html(body)}\\]</span>'

    def latex_environment(self, name: str, body: str) -> str:
        name, body = self.escape_html(name), self.escape_html(body)
        return f'<span class="arithmatex">\\[\\begin{{{name}}}{body}\\end{{{name}}}\\]</span>'

    IPythonRenderer.inline_math = inline_math
    IPythonRenderer.block_math = block_math
    IPythonRenderer.latex_environment = latex_environment


def on_config(config):
    _mark_notebook_maths()
    return config


# nbconvert's template loads MathJax from an address the site does not set (an empty
# script); KaTeX typesets the notebooks as it does every other page.
_MATHJAX_LOADER = re.compile(r"<!-- Load mathjax -->.*?<!-- End of mathjax configuration -->", re.S)
_HEADING = re.compile(r"<h([1-6])((?:\s[^>]*)?)>(.*?)</h\1>", re.S)
_ANCHOR_LINK = re.compile(r'<a class="anchor-link"[^>]*>.*?</a>', re.S)
_LINK_TAG = re.compile(r"</?a\b[^>]*>")
_ID = re.compile(r'\sid="([^"]*)"')


def _slug(text: str, taken: set[str]) -> str:
    base = re.sub(r"[^\w]+", "-", html.unescape(re.sub(r"<[^>]+>", "", text)).lower()).strip("-") or "section"
    slug, n = base, 1
    while slug in taken:
        n += 1
        slug = f"{base}-{n}"
    return slug


def notebook_headings(content: str) -> tuple[str, list[dict]]:
    """``(content, toc_tokens)``: every heading given an id (if it had none) and the table of contents they make.

    A token is ``{"level", "id", "name", "children"}`` (the shape Python-Markdown's
    ``toc_tokens`` have); its name is the heading's HTML without its anchor link, its
    formulas kept.
    """
    taken = set(_ID.findall(content))
    flat = []

    def heading(match: re.Match) -> str:
        level, attributes, inner = int(match[1]), match[2], match[3]
        found = _ID.search(attributes)
        if found:
            anchor = found[1]
        else:
            anchor = _slug(_ANCHOR_LINK.sub("", inner), taken)
            taken.add(anchor)
            attributes = f' id="{anchor}"{attributes}'
        name = _LINK_TAG.sub("", _ANCHOR_LINK.sub("", inner)).strip()
        flat.append({"level": level, "id": anchor, "name": name, "children": []})
        return f"<h{level}{attributes}>{inner}</h{level}>"

    content = _HEADING.sub(heading, content)
    tokens: list[dict] = []
    stack: list[dict] = []
    for token in flat:
        while stack and stack[-1]["level"] >= token["level"]:
            stack.pop()
        (stack[-1]["children"] if stack else tokens).append(token)
        stack.append(token)
    return content, tokens


def on_page_content(content, page, config, files):
    if not page.file.src_uri.endswith(".ipynb"):
        return content
    content, tokens = notebook_headings(_MATHJAX_LOADER.sub("", content))
    page.toc = get_toc(tokens)
    return content
