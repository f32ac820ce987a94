"""The documentation site: its strict build, its API reference, and the getting-started code.

The site is built with ``mkdocs build --strict`` (the ``docs`` extra: mkdocs-material,
mkdocstrings, mkdocs-jupyter); a broken link, an unresolved cross-reference or a public
name without a docstring fails it. The built pages are then read as a reader sees them:
every formula typeset by the bundled KaTeX (no raw ``$...$``), every table-of-contents
entry landing on its heading. Without the ``docs`` extra those tests skip; the code
blocks of the getting-started page run either way.
"""

from __future__ import annotations

import ast
import importlib.util
import json
import logging
import os
import pathlib
import re
import subprocess
import sys
from html.parser import HTMLParser

import matplotlib
import numpy as np

matplotlib.use("Agg")

import pytest

import jaxbill as jb

ROOT = pathlib.Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"


def _code_blocks(path: pathlib.Path, language: str) -> list[str]:
    return re.findall(rf"^```{language}\n(.*?)^```", path.read_text(), flags=re.S | re.M)


def _needs_docs_extra(what: str) -> None:
    """Skip without mkdocs, naming the extra; with ``JAXBILL_DOCS_REQUIRED=1`` (CI's second stage, which
    installs the extra) fail instead, so that a broken install cannot pass as a skip."""
    if os.environ.get("JAXBILL_DOCS_REQUIRED") == "1":
        import mkdocs  # noqa: F401
    else:
        pytest.importorskip("mkdocs", reason=f"{what} needs the docs extra: pip install -e '.[docs]'")


def _load_hooks():
    _needs_docs_extra("docs/hooks.py")
    spec = importlib.util.spec_from_file_location("jaxbill_docs_hooks", DOCS / "hooks.py")
    hooks = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hooks)
    return hooks


@pytest.fixture(scope="module")
def hooks():
    """``docs/hooks.py``, loaded once (the docs extra)."""
    return _load_hooks()


def test_getting_started_python_blocks_run(tmp_path, monkeypatch, capsys):
    """Every python block of the getting-started page, run in order in one namespace, as a reader would."""
    blocks = _code_blocks(DOCS / "getting-started.md", "python")
    assert len(blocks) == 3, "the page has the five lines, the figure and the batches"
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    for number, block in enumerate(blocks, 1):
        try:
            exec(compile(block, f"getting-started.md, python block {number}", "exec"), namespace)
        except Exception as error:  # report which block broke, with the error
            pytest.fail(f"python block {number} of getting-started.md raised {type(error).__name__}: {error}")
    # The five lines print the conserved energy and angular momentum of the orbit's last state.
    printed = [float(v) for v in capsys.readouterr().out.split()]
    scene, state0 = namespace["scene"], namespace["state0"]
    assert printed == pytest.approx(
        [float(jb.energy(scene, state0)), float(jb.angular_momentum(scene, state0))], rel=1e-12
    )
    assert (tmp_path / "orbit.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert namespace["batch"].state.shape == (2, 1000, 6)
    assert namespace["new_states"].shape == (3, 6)


def _run_blocks(blocks: list[str], where: str, capsys) -> tuple[dict, list[str]]:
    """Run code blocks in order in one namespace, as a reader would: ``(namespace, what each block printed)``."""
    namespace: dict = {}
    printed = []
    for number, block in enumerate(blocks, 1):
        try:
            exec(compile(block, f"{where}, python block {number}", "exec"), namespace)
        except Exception as error:  # report which block broke, with the error
            pytest.fail(f"python block {number} of {where} raised {type(error).__name__}: {error}")
        printed.append(capsys.readouterr().out)
    return namespace, printed


def test_the_composition_examples_of_the_readme_and_the_home_page_run(capsys):
    """The triangle in the stadium: its energy is conserved over the orbit and its largest exponent is positive
    (the stadium is chaotic); the home page prints what the README prints."""
    namespace, printed = _run_blocks(_code_blocks(ROOT / "README.md", "python"), "README.md", capsys)
    scene, state0 = namespace["scene"], namespace["state0"]
    assert isinstance(scene, jb.BodyInTable)
    energy, exponent = (float(v) for v in printed[-1].split())
    assert energy == pytest.approx(float(scene.energy(state0)), rel=1e-12)
    assert 0.1 < exponent < 100.0
    assert set(np.unique(np.asarray(namespace["orb"].contact)).tolist()) <= set(scene.gap_codes)
    _, home = _run_blocks(_code_blocks(DOCS / "index.md", "python"), "index.md", capsys)
    assert home[-1] == printed[-1]


# a block that quotes the library's code: its first line names the file
QUOTE_MARK = re.compile(r"^# from (jaxbill/\S+\.py)\n")


def _unquoted_line(path: str, block: str) -> str | None:
    """The first line of ``block`` that ``path`` does not have, in that order (lines may be left out); None."""
    source = [line.strip() for line in (ROOT / path).read_text().splitlines()]
    position = 0
    for line in (line.strip() for line in block.splitlines()):
        if not line:
            continue
        if line not in source[position:]:
            return line
        position = source.index(line, position) + 1
    return None


@pytest.mark.parametrize("page", ["how-to/new-table.md", "how-to/new-body.md"])
def test_the_how_to_pages_quote_the_code_as_it_is(page):
    """A block marked ``# from <file>`` shows that file's lines in their order: the pages walk through the code as
    it is, not as it was."""
    quotes = [QUOTE_MARK.match(b) for b in _code_blocks(DOCS / page, "python")]
    quotes = [(m[1], b[m.end() :]) for m, b in zip(quotes, _code_blocks(DOCS / page, "python")) if m]
    assert len(quotes) >= 5, page
    for path, block in quotes:
        missing = _unquoted_line(path, block)
        assert missing is None, f"{page} quotes {path} with a line it does not have there: {missing!r}"


def test_the_quote_check_sees_a_changed_line():
    block = "    def gap(self, x, y):\n        qx, qy = self._offset(x, y)\n        return self.radius**2 - qx * qx\n"
    assert _unquoted_line("jaxbill/_scenes/tables/stadium.py", block) == "return self.radius**2 - qx * qx"
    swapped = "    def gradient(self, x, y):\n    def gap(self, x, y):\n"
    assert _unquoted_line("jaxbill/_scenes/tables/stadium.py", swapped) == "def gap(self, x, y):"


@pytest.mark.parametrize("page", ["concepts.md", "how-to/new-table.md", "how-to/new-body.md"])
def test_the_composition_pages_examples_run_and_say_what_they_do(page, capsys):
    """The runnable blocks (not the quotes): an orbit conserves its energy and touches only the scene's gaps; the
    gap names a comment shows are the scene's."""
    blocks = [b for b in _code_blocks(DOCS / page, "python") if not QUOTE_MARK.match(b)]
    assert blocks, page
    namespace, _ = _run_blocks(blocks, page, capsys)
    scene = namespace["scene"]
    if "orb" in namespace:
        orb = namespace["orb"]
        np.testing.assert_allclose(
            np.asarray(jb.energy(scene, orb.state)), float(jb.energy(scene, namespace["state0"])), rtol=1e-12
        )
        assert set(np.unique(np.asarray(orb.contact)).tolist()) <= set(scene.gap_codes)
    shown = re.search(r"scene\.gap_names +# (\(.*\))", "\n".join(blocks))
    if shown:
        assert scene.gap_names == ast.literal_eval(shown[1])


def test_getting_started_commands_are_the_readmes():
    """The two set-up commands on the page are the README's, word for word."""
    page = _code_blocks(DOCS / "getting-started.md", "bash")[0]
    readme = _code_blocks(ROOT / "README.md", "bash")[0]
    assert page.strip().splitlines()[:2] == readme.strip().splitlines()[:2]


def test_every_public_name_has_a_documented_api_entry(caplog, hooks):
    with caplog.at_level(logging.WARNING, logger="mkdocs.hooks.jaxbill"):
        pages = hooks.api_pages()
    assert not caplog.records, "\n".join(r.getMessage() for r in caplog.records)
    reference = "\n".join(pages.values())
    for name in jb.__all__:
        assert f"::: jaxbill.{name}\n" in reference or f"`jaxbill.{name}`" in reference, name
    assert "::: jaxbill.plotting" in reference


def test_a_public_name_without_a_docstring_is_a_warning(caplog, monkeypatch, hooks):

    def undocumented():
        pass

    monkeypatch.setattr(jb, "undocumented", undocumented, raising=False)
    monkeypatch.setattr(jb, "__all__", [*jb.__all__, "undocumented"])
    with caplog.at_level(logging.WARNING, logger="mkdocs.hooks.jaxbill"):
        pages = hooks.api_pages()
    assert any("jaxbill.undocumented has no docstring" in r.getMessage() for r in caplog.records)
    assert "::: jaxbill.undocumented" in pages[hooks.MORE_PAGE]
    assert any("public names on no API page" in r.getMessage() for r in caplog.records)


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> pathlib.Path:
    """The site, built once with ``mkdocs build --strict`` (a failed build fails every test that reads it)."""
    _needs_docs_extra("the site")
    site = tmp_path_factory.mktemp("docs") / "site"
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1", JAX_PLATFORMS="cpu")
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(site)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-4000:]
    return site


def _pages(site: pathlib.Path) -> list[pathlib.Path]:
    return sorted(p for p in site.rglob("*.html") if p.name != "404.html")


def test_docs_build_strict(site):
    scenes = (site / "api" / "scenes" / "index.html").read_text()
    assert 'id="jaxbill.StickInCircle"' in scenes
    assert 'id="jaxbill.explore"' in (site / "api" / "explorer" / "index.html").read_text()
    for notebook in sorted((ROOT / "notebooks").glob("*.ipynb")):
        page = (site / "notebooks" / notebook.stem / "index.html").read_text()
        assert "data:image/png" in page, f"{notebook.name} is rendered without its stored figures"
    assert (site / "images" / "explorer.png").exists()


class _ReadText(HTMLParser):
    """The text a reader sees as prose: outside code, scripts, styles and the formulas marked for KaTeX.

    (Also outside a notebook cell's hidden copy of its code, kept for the copy button.)
    """

    VOID = {"area", "base", "br", "col", "embed", "hr", "img", "input", "link", "meta", "source", "track", "wbr"}
    SKIPPED = {"pre", "code", "kbd", "samp", "script", "style", "textarea", "svg"}

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.open: list[tuple[str, bool]] = []  # (tag, skipped), innermost last
        self.text: list[str] = []

    def handle_starttag(self, tag, attrs):
        if tag in self.VOID:
            return
        classes = (dict(attrs).get("class") or "").split()
        self.open.append((tag, tag in self.SKIPPED or bool({"arithmatex", "clipboard-copy-txt"} & set(classes))))

    def handle_endtag(self, tag):
        for depth in range(len(self.open) - 1, -1, -1):  # tolerate an unclosed element inside
            if self.open[depth][0] == tag:
                del self.open[depth:]
                return

    def handle_data(self, data):
        if not any(skipped for _, skipped in self.open):
            self.text.append(data)


def _prose(page: pathlib.Path) -> str:
    reader = _ReadText()
    reader.feed(page.read_text())
    return "".join(reader.text)


# a formula left as typed: $...$ or $$...$$ (what nbconvert and Markdown leave), or TeX
# delimiters outside an element the maths script typesets
RAW_MATHS = re.compile(r"\$\$|\$(?=\S)[^$\n]{1,300}?(?<=\S)\$|\\\(.*?\\\)|\\\[.*?\\\]", re.S)


def test_every_formula_on_the_site_is_typeset(site):
    """No page, notebook pages, headings and tables of contents included, shows a formula as raw TeX."""
    raw = {}
    for page in _pages(site):
        found = RAW_MATHS.findall(_prose(page))
        if found:
            raw[str(page.relative_to(site))] = found[:3]
    assert not raw, f"raw maths on {len(raw)} pages: {raw}"


def test_the_raw_maths_check_sees_what_nbconvert_and_markdown_leave(tmp_path):
    """The check above is not vacuous: it finds untypeset formulas where a reader would see them."""
    page = tmp_path / "page.html"
    page.write_text(
        '<nav><a href="#x">No web at $\\varepsilon = 0$</a></nav><p>$$\\omega\' = \\omega$$ and <code>$HOME</code></p>'
        '<p><span class="arithmatex">\\(\\ell\\)</span> costs \\(a\\) and <script>var a = "$x$";</script></p>'
    )
    assert RAW_MATHS.findall(_prose(page)) == ["$\\varepsilon = 0$", "$$", "$$", "\\(a\\)"]


def test_notebook_formulas_are_marked_for_katex_which_the_site_carries(site):
    """Every notebook with maths in its Markdown gets it marked on its page; KaTeX and its fonts are local files."""
    for notebook in sorted((ROOT / "notebooks").glob("*.ipynb")):
        cells = json.loads(notebook.read_text())["cells"]
        if any("$" in "".join(c["source"]) for c in cells if c["cell_type"] == "markdown"):
            page = (site / "notebooks" / notebook.stem / "index.html").read_text()
            assert page.count('class="arithmatex"') >= 5, notebook.name
    katex = site / "assets" / "katex"
    stylesheet = (katex / "katex.min.css").read_text()
    fonts = re.findall(r"url\((fonts/[^)]+\.woff2)\)", stylesheet)
    assert len(fonts) >= 20 and all((katex / font).is_file() for font in fonts)
    for page in _pages(site):
        text = page.read_text()
        assert "assets/katex/katex.min.js" in text and "assets/render-maths.js" in text, page
        assert not re.search(r'<script[^>]+src="(https?:)?//', text), f"{page} loads a script from the network"
        assert "mathjax" not in text.lower(), f"{page} still loads MathJax"


def test_every_table_of_contents_entry_links_to_a_heading_on_its_page(site):
    for page in _pages(site):
        text = page.read_text()
        anchors = set(re.findall(r'\sid="([^"]+)"', text))
        links = re.findall(r'<a href="#([^"]+)" class="md-nav__link"', text)
        broken = [link for link in links if link not in anchors]
        assert not broken, f"{page.relative_to(site)}: {broken}"


SCENE_CLASSES = ("StickInCircle", "StickInEllipse", "StickBetweenWalls2D", "StickBetweenWalls3D")


def test_engine_members_named_in_the_hooks_exist(hooks):
    """``ENGINE_MEMBERS`` names no member that no scene has (a stale name would hide nothing)."""
    scenes = [getattr(jb, name) for name in SCENE_CLASSES]
    stale = [m for m in hooks.ENGINE_MEMBERS if not any(hasattr(cls, m) for cls in scenes)]
    assert not stale, stale


def test_the_scenes_page_shows_the_user_s_members_and_the_scene_page_the_engine_s(site, hooks):
    """What a user calls is on the scenes page, typed; what the engine calls only on the page for adding a scene."""
    from jaxbill._scenes.protocols import Scene

    scenes = (site / "api" / "scenes" / "index.html").read_text()
    new_scene = (site / "how-to" / "new-scene" / "index.html").read_text()
    shown = set(re.findall(r'id="jaxbill\.(?:' + "|".join(SCENE_CLASSES) + r')\.(\w+)"', scenes))
    assert not shown & set(hooks.ENGINE_MEMBERS), shown & set(hooks.ENGINE_MEMBERS)
    assert {"energy", "end_points", "gaps", "flight", "section", "section_state", "focal_momentum_product"} <= shown
    protocol = [
        name
        for name, value in vars(Scene).items()
        if not name.startswith("_") and (callable(value) or isinstance(value, property))
    ]
    assert "root_search" in protocol and "energy" in protocol
    for name in protocol:
        on_scene_page = f'id="jaxbill._scenes.protocols.Scene.{name}"' in new_scene
        assert on_scene_page, f"Scene.{name} is not documented on the page for adding a scene"
        assert (name in hooks.ENGINE_MEMBERS) != (name in shown), f"{name}: on both pages or on neither"
    # every parameter of every scene has a type in its table
    rows = re.findall(
        r'<tr class="doc-section-item">\s*<td>\s*<code>([^<]*)</code>\s*</td>\s*<td>(.*?)</td>', scenes, re.S
    )
    assert len(rows) >= 17
    untyped = [name for name, cell in rows if not cell.strip()]
    assert not untyped, untyped


BODIES_AND_TABLES = (
    *("PointBody", "Dumbbell", "PolygonBody", "EllipseBody"),
    *("Circle", "Ellipse", "Stadium", "Polygon", "Strip", "ConvexTable"),
)


def test_the_bodies_page_shows_the_user_s_members_and_the_extending_page_the_scene_s(site, hooks):
    """A composed scene's page shows what a user calls, not what the engine calls; a body's or a table's shows
    none of its answers to the scene, which the bases on the page for extending show."""
    page = (site / "api" / "bodies" / "index.html").read_text()
    scene = set(re.findall(r'id="jaxbill\.BodyInTable\.(\w+)"', page))
    assert {"gaps", "energy", "section", "contact_points", "gap_codes"} <= scene, scene
    assert not scene & set(hooks.ENGINE_MEMBERS), scene & set(hooks.ENGINE_MEMBERS)
    parts = set(re.findall(r'id="jaxbill\.(?:' + "|".join(BODIES_AND_TABLES) + r')\.(\w+)"', page))
    assert "vertices" in parts and not parts & set(hooks.PART_MEMBERS), parts
    extending = (site / "api" / "extending" / "index.html").read_text()
    bases = set(re.findall(r'id="jaxbill\.(?:Body|Table|Piece)\.(\w+)"', extending))
    assert {"offsets", "turn_vector", "inner_radius2", "pieces", "curvature_bounds", "quiet_interval"} <= bases
    assert {"exit_time", "impulse_normal", "boundary_coordinate"} <= bases


def test_the_api_reference_has_no_page_of_leftovers(site):
    assert not (site / "api" / "more" / "index.html").exists()
    runs = (site / "api" / "runs" / "index.html").read_text()
    assert 'id="jaxbill.backend_settings"' in runs
    studies = (site / "api" / "studies" / "index.html").read_text()
    assert 'id="jaxbill.studies.small_stick.study_scene"' in studies
    assert 'id="jaxbill.studies.arnold_web.web_starts"' in studies
    # documented once: the top-level names the studies share are on the derivatives page only
    assert 'id="jaxbill.studies.small_stick.ensemble_lyapunov"' not in studies
    plotting = (site / "api" / "plotting" / "index.html").read_text()
    assert 'id="jaxbill.plotting.draw_ellipse_orbit"' in plotting
