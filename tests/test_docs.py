"""The documentation site: its strict build, its API reference, and the getting-started code.

The site is built with ``mkdocs build --strict`` (the ``docs`` extra: mkdocs-material,
mkdocstrings, mkdocs-jupyter); a broken link, an unresolved cross-reference or a public
name without a docstring fails it. Without the ``docs`` extra the build test and the tests
of the API reference's hooks (which import mkdocs) skip; the code blocks of the
getting-started page run either way.
"""

from __future__ import annotations

import importlib.util
import logging
import os
import pathlib
import re
import subprocess
import sys

import matplotlib

matplotlib.use("Agg")

import pytest

import jaxbill as jb

ROOT = pathlib.Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"


def _code_blocks(path: pathlib.Path, language: str) -> list[str]:
    return re.findall(rf"^```{language}\n(.*?)^```", path.read_text(), flags=re.S | re.M)


NEEDS_DOCS_EXTRA = "needs the docs extra: pip install -e '.[docs]'"


def _load_hooks():
    pytest.importorskip("mkdocs", reason=NEEDS_DOCS_EXTRA)
    spec = importlib.util.spec_from_file_location("jaxbill_docs_hooks", DOCS / "hooks.py")
    hooks = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hooks)
    return hooks


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


def test_getting_started_commands_are_the_readmes():
    """The two set-up commands on the page are the README's, word for word."""
    page = _code_blocks(DOCS / "getting-started.md", "bash")[0]
    readme = _code_blocks(ROOT / "README.md", "bash")[0]
    assert page.strip().splitlines()[:2] == readme.strip().splitlines()[:2]


def test_every_public_name_has_a_documented_api_entry(caplog):
    hooks = _load_hooks()
    with caplog.at_level(logging.WARNING, logger="mkdocs.hooks.jaxbill"):
        pages = hooks.api_pages()
    assert not caplog.records, "\n".join(r.getMessage() for r in caplog.records)
    reference = "\n".join(pages.values())
    for name in jb.__all__:
        assert f"::: jaxbill.{name}\n" in reference or f"`jaxbill.{name}`" in reference, name
    assert "::: jaxbill.plotting" in reference


def test_a_public_name_without_a_docstring_is_a_warning(caplog, monkeypatch):
    hooks = _load_hooks()

    def undocumented():
        pass

    monkeypatch.setattr(jb, "undocumented", undocumented, raising=False)
    monkeypatch.setattr(jb, "__all__", [*jb.__all__, "undocumented"])
    with caplog.at_level(logging.WARNING, logger="mkdocs.hooks.jaxbill"):
        pages = hooks.api_pages()
    assert any("jaxbill.undocumented has no docstring" in r.getMessage() for r in caplog.records)
    assert "::: jaxbill.undocumented" in pages[hooks.MORE_PAGE]


@pytest.mark.skipif(importlib.util.find_spec("mkdocs") is None, reason=NEEDS_DOCS_EXTRA)
def test_docs_build_strict(tmp_path):
    site = tmp_path / "site"
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
    scenes = (site / "api" / "scenes" / "index.html").read_text()
    assert 'id="jaxbill.StickInCircle"' in scenes
    assert 'id="jaxbill.explore"' in (site / "api" / "explorer" / "index.html").read_text()
    for notebook in sorted((ROOT / "notebooks").glob("*.ipynb")):
        page = (site / "notebooks" / notebook.stem / "index.html").read_text()
        assert "data:image/png" in page, f"{notebook.name} is rendered without its stored figures"
    assert (site / "images" / "explorer.png").exists()
