"""Every notebook in notebooks/ executes top to bottom without error.

The book's FOC demo notebook is in the fast tier; the others each compile tens of programs (20-35 s on 2
cores) and run in the whole suite."""

from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

NOTEBOOKS = sorted((Path(__file__).resolve().parents[2] / "notebooks").glob("*.ipynb"))
FAST = {"01_book_foc_demo.ipynb"}
CASES = [pytest.param(p, id=p.name, marks=() if p.name in FAST else pytest.mark.slow) for p in NOTEBOOKS]


def test_there_are_notebooks():
    assert NOTEBOOKS, "notebooks/ holds no notebook"
    assert FAST <= {p.name for p in NOTEBOOKS}, "a fast-tier notebook is missing"


@pytest.mark.parametrize("path", CASES)
def test_notebook_runs(path, tmp_path):
    nb = nbformat.read(path, as_version=4)
    client = NotebookClient(
        nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": tmp_path}}
    )
    client.execute()
    errors = [
        o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", []) if o.output_type == "error"
    ]
    assert not errors
