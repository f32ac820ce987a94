"""What a user reads teaches only public names and speaks of the library and its science only.

The notebooks (and the scripts beside them that make their data), the documentation pages
and the README are what a user copies from: none imports a private module (``jaxbill._...``),
and the notebooks and the README do not even name one. Two files are exempt, being about
the insides: ``docs/hooks.py`` (it builds the site) and ``docs/how-to/new-scene.md`` (the
engine's internals, for whoever adds a scene).

None of those, nor a docstring of the package, speaks of how the project is run (issues,
their items, sessions) or of files outside the repository.

No docstring or comment of the package states a measured speed ("1.4x faster", "0.97x",
"2.5 ns a lane"): such a figure goes stale with the next change to the engine, the compiler
or the machine. The source says why it is written the way it is; the figures belong to the
benchmarks, which print them, and to the performance page, which quotes their results.
"""

from __future__ import annotations

import ast
import io
import json
import pathlib
import re
import tempfile
import tokenize

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent
EXEMPT = {ROOT / "docs" / "hooks.py", ROOT / "docs" / "how-to" / "new-scene.md"}

PRIVATE_IMPORT = re.compile(
    r"^[ \t>]*(from\s+jaxbill\._\w*[\w.]*\s+import|import\s+jaxbill\._|from\s+jaxbill\s+import\s+_)", re.M
)
PRIVATE_NAME = re.compile(r"\bjaxbill\._\w")
# how the project is run, or where its notes live: never the reader's business. The folder this
# checkout lies in (where other checkouts and notes may lie) is read here, not written down; a folder
# every machine shares (the root, the temporary folder, the home folders) names nothing of ours, and a
# notebook may well write its scratch files there.
SHARED_FOLDERS = {
    pathlib.Path(folder).resolve() for folder in ("/", "/tmp", tempfile.gettempdir(), pathlib.Path.home(), "/home")
}
WHERE_WE_LIE = ROOT.parent.resolve()
OUTSIDE = r"(?!)" if WHERE_WE_LIE in SHARED_FOLDERS else re.escape(str(WHERE_WE_LIE) + "/")
PROCESS_WORDS = re.compile(
    r"\b[Ii]ssue\s*#?\d+|\b[Ii]tems?\s+\d+(?:\s*(?:,|and)\s*\d+)*\s+of\b|physics\.md|physics notes"
    rf"|{OUTSIDE}|\bsessions?\b"
)
# a measured speed: a ratio ("1.4x", "10-20x faster"), a percentage faster or slower, or a time per
# lane or call in ns, us or ms; not a matrix's shape ("2x2", "2 x 2") nor a hexadecimal float ("0x1.9p+1")
SPEED_FIGURE = re.compile(
    r"\b\d+(?:\.\d+)?(?:-\d+(?:\.\d+)?)?x\b"
    r"|\b\d+(?:\.\d+)?(?:-\d+(?:\.\d+)?)?\s*(?:%|percent)\s+(?:faster|slower)"
    r"|\b(?:twice|\d+(?:\.\d+)? times)\s+(?:as fast|as slow|faster|slower)"
    r"|\b\d+(?:\.\d+)?\s*(?:ns|us|µs|ms)\b"
)


def _notebook_text(path: pathlib.Path) -> str:
    """A notebook's cell sources (not its outputs), one cell after another."""
    cells = json.loads(path.read_text())["cells"]
    return "\n".join("".join(cell["source"]) for cell in cells)


def _user_files() -> dict[pathlib.Path, str]:
    files = {path: _notebook_text(path) for path in sorted((ROOT / "notebooks").rglob("*.ipynb"))}
    files |= {path: path.read_text() for path in sorted((ROOT / "notebooks").rglob("*.py"))}
    files |= {path: path.read_text() for path in sorted((ROOT / "docs").rglob("*.md")) if path not in EXEMPT}
    files[ROOT / "README.md"] = (ROOT / "README.md").read_text()
    return files


def _docstrings(path: pathlib.Path) -> list[tuple[int, str]]:
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
            doc = ast.get_docstring(node, clean=False)
            if doc:
                found.append((getattr(node, "lineno", 1), doc))
    return found


def _comments(path: pathlib.Path) -> list[tuple[int, str]]:
    tokens = tokenize.generate_tokens(io.StringIO(path.read_text()).readline)
    return [(token.start[0], token.string) for token in tokens if token.type == tokenize.COMMENT]


def test_there_is_something_to_read():
    names = {path.name for path in _user_files()}
    assert {"01_quickstart.ipynb", "10_arnold_web.ipynb", "README.md", "getting-started.md", "index.md"} <= names


def test_no_user_file_imports_a_private_module():
    offending = {
        str(path.relative_to(ROOT)): PRIVATE_IMPORT.findall(text)[:3]
        for path, text in _user_files().items()
        if PRIVATE_IMPORT.search(text)
    }
    assert not offending, offending


def test_notebooks_and_readme_name_no_private_module():
    files = {p: t for p, t in _user_files().items() if p.suffix == ".ipynb" or p.name == "README.md"}
    offending = {
        str(p.relative_to(ROOT)): PRIVATE_NAME.findall(t)[:3] for p, t in files.items() if PRIVATE_NAME.search(t)
    }
    assert not offending, offending


def test_user_text_speaks_of_the_library_only():
    offending = {
        str(path.relative_to(ROOT)): PROCESS_WORDS.findall(text)[:3]
        for path, text in _user_files().items()
        if PROCESS_WORDS.search(text)
    }
    for path in sorted((ROOT / "jaxbill").rglob("*.py")):
        for line, doc in _docstrings(path):
            if PROCESS_WORDS.search(doc):
                offending[f"{path.relative_to(ROOT)}:{line}"] = PROCESS_WORDS.findall(doc)[:3]
    assert not offending, offending


def test_no_source_text_states_a_measured_speed():
    offending = {}
    for path in sorted((ROOT / "jaxbill").rglob("*.py")):
        for line, text in _docstrings(path) + _comments(path):
            if SPEED_FIGURE.search(text):
                offending[f"{path.relative_to(ROOT)}:{line}"] = SPEED_FIGURE.findall(text)[:3]
    assert not offending, offending


def test_the_comments_are_read():
    comments = [text for _, text in _comments(ROOT / "jaxbill" / "_engine" / "pallas.py")]
    assert any("Orbits per kernel program" in text for text in comments)


@pytest.mark.parametrize(
    "text",
    [
        "(one orbit of the walls 1.1x faster)",
        "walls 0.5x",
        "64 on 2 warps reached 0.97x that",
        "one orbit runs 10-20x faster",
        "its sort op ran 50x slower",
        "14 ns a lane",
        "2.5 ns a lane against 0.64 ns with AVX2",
        "cost 0.2 ms of every call",
        "ran 1.5-2.5% faster without it",
        "twice as fast",
    ],
)
def test_the_speed_check_sees_measured_speeds(text):
    assert SPEED_FIGURE.search(text)


@pytest.mark.parametrize(
    "text",
    [
        "a 2x2 matrix",
        "a ``2 x 2`` matrix with multipliers ``mu, 1/mu``",
        "an inexact wrap (``x - 2 pi floor(x / 2 pi)``)",
        "a 150 x 150 grid",
        'float.fromhex("0x1.921fb00000000p+0")',
        "within ``1.11 * 2**-53`` absolute for ``|phi| < 1e4``",
        "the last 4; every lane of a chunk narrower than 16",
        "it then quadruples after every call",
    ],
)
def test_the_speed_check_leaves_other_figures_alone(text):
    assert not SPEED_FIGURE.search(text)


@pytest.mark.parametrize(
    "text",
    [
        "from jaxbill._analysis import arnold_web as aw",
        "import jaxbill._engine.collision",
        "    from jaxbill._scenes.circle.sections import (\n    x,\n)",
        "from jaxbill import _figures",
    ],
)
def test_the_private_import_check_sees_private_imports(text):
    assert PRIVATE_IMPORT.search(text)


@pytest.mark.parametrize(
    "text", ["from jaxbill import plotting", "import jaxbill as jb", "from jaxbill.studies import small_stick"]
)
def test_the_private_import_check_passes_public_ones(text):
    assert not PRIVATE_IMPORT.search(text)


@pytest.mark.parametrize(
    "text",
    [
        "Issue 20, item 2.",
        "issue 36",
        "(``physics.md``)",
        "(physics notes, *Averages*)",
        "items 3 and 4 of it",
        "this session",
    ],
)
def test_the_process_words_check_sees_them(text):
    assert PROCESS_WORDS.search(text)


def test_the_folder_around_the_checkout_is_seen_unless_every_machine_has_it():
    notes = f"see {WHERE_WE_LIE / 'notes' / 'plan.md'}"
    assert bool(PROCESS_WORDS.search(notes)) == (WHERE_WE_LIE not in SHARED_FOLDERS)
    assert not PROCESS_WORDS.search('small_stick_figure("/tmp/jaxbill_small_stick")')


def test_the_process_words_check_leaves_science_alone():
    text = "the second issue with chaotic orbits; 12 items per batch; a resonance of order 9"
    assert not PROCESS_WORDS.search(text)


def test_the_paper_is_cited_where_a_newcomer_looks():
    """Authors, title and where it appeared on the first pages; the papers it builds on beside the full reference."""
    for name in ("README.md", "docs/index.md", "docs/getting-started.md", "notebooks/02_paper.ipynb"):
        path = ROOT / name
        text = " ".join((_notebook_text(path) if path.suffix == ".ipynb" else path.read_text()).split())
        assert "R. Chatterjee and A. D. Jackson" in text and "Surfing Arnold's Web" in text, name
        assert "96-57" in text and "1996" in text, f"{name} does not say where the paper appeared"
    for name in ("README.md", "docs/index.md"):
        text = " ".join((ROOT / name).read_text().split())
        assert "mp_arc/html/papers/96-57" in text, name
        assert '"Coin tossing as a billiard problem", Phys. Rev. E **52**, 3608 (1995)' in text, name
        assert "95-495" in text and "Lichtenberg and M. A. Lieberman" in text, name
