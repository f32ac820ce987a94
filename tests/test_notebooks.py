"""Every notebook in ``notebooks/`` runs top to bottom without error.

Each ``notebooks/*.ipynb`` is executed with nbclient in a fresh kernel (the
``python3`` kernel of the running interpreter), with a time limit per cell;
any cell that raises fails the test. Outputs are not compared: the committed
notebooks carry the outputs of their last full run. The two studies (09, 10), the
gallery of bodies in tables (11) and the standard billiards' reference numbers (12)
end with assertions on the numbers they recompute, within the error bars they
compute, so that a changed verdict fails here too.

To re-execute the notebooks and save their outputs in place::

    python tests/test_notebooks.py            # all notebooks
    python tests/test_notebooks.py notebooks/02_paper.ipynb
"""

from __future__ import annotations

import pathlib
import sys
import time

import pytest

nbformat = pytest.importorskip("nbformat") if __name__ != "__main__" else __import__("nbformat")
nbclient = pytest.importorskip("nbclient") if __name__ != "__main__" else __import__("nbclient")

NOTEBOOKS = pathlib.Path(__file__).resolve().parent.parent / "notebooks"
CELL_TIMEOUT = 600  # seconds per cell


def execute(path: pathlib.Path):
    """Run a notebook top to bottom in its own folder; return the executed notebook."""
    notebook = nbformat.read(path, as_version=4)
    client = nbclient.NotebookClient(
        notebook,
        timeout=CELL_TIMEOUT,
        kernel_name="python3",
        resources={"metadata": {"path": str(path.parent)}},
    )
    client.execute()
    return notebook


@pytest.mark.parametrize("path", sorted(NOTEBOOKS.glob("*.ipynb")), ids=lambda p: p.name)
def test_notebook_runs(path):
    notebook = execute(path)
    errors = [
        output
        for cell in notebook.cells
        if cell.cell_type == "code"
        for output in cell.get("outputs", [])
        if output.get("output_type") == "error"
    ]
    assert not errors, f"{path.name}: {errors[0]['ename']}: {errors[0]['evalue']}"


@pytest.mark.parametrize(
    "name",
    ["09_small_stick_chaos.ipynb", "10_arnold_web.ipynb", "11_bodies_and_tables.ipynb", "12_standard_billiards.ipynb"],
)
def test_the_studies_end_by_asserting_what_they_recompute(name):
    """The studies' verdicts are held by assertions in their last cell, which fail the run above."""
    code = [cell for cell in nbformat.read(NOTEBOOKS / name, as_version=4).cells if cell.cell_type == "code"]
    assert "assert " in code[-1].source, f"{name} no longer ends with its assertions"


def test_there_are_notebooks():
    names = {p.name for p in NOTEBOOKS.glob("*.ipynb")}
    assert {"01_quickstart.ipynb", "02_paper.ipynb", "03_beyond_the_paper.ipynb"} <= names


if __name__ == "__main__":
    targets = [pathlib.Path(a).resolve() for a in sys.argv[1:]] or sorted(NOTEBOOKS.glob("*.ipynb"))
    for target in targets:
        start = time.perf_counter()
        nbformat.write(execute(target), target)
        print(f"{target.name}: executed and saved in {time.perf_counter() - start:.0f} s")
