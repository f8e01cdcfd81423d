"""Executing a notebook of notebooks/ top to bottom, for the test files of this folder.

The notebooks are split over several test files only so that ``--dist loadfile`` (pyproject.toml) can
spread them over the workers: each takes tens of seconds, and one file of all thirteen was the suite's
longest unit. ``GROUPS`` says which file runs which notebook; test_notebooks.py checks that every
notebook is in exactly one group.
"""

from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

NOTEBOOKS = sorted((Path(__file__).resolve().parents[2] / "notebooks").glob("*.ipynb"))
#: The fast tier's notebook; the others each compile tens of programs and run in the whole suite.
FAST = {"01_book_foc_demo.ipynb"}
#: The notebooks each test file runs (roughly equal times; 12 alone is about as long as three others).
GROUPS = {
    "test_notebooks.py": ("01", "02", "03", "04", "05"),
    "test_notebooks_controls.py": ("06", "07", "09", "13"),
    "test_notebooks_multiphase.py": ("08", "10", "11"),
    "test_notebooks_commissioning.py": ("12",),
}


def cases(group: str):
    """The ``pytest.param`` of each notebook of ``group`` (a key of ``GROUPS``)."""
    chosen = [p for p in NOTEBOOKS if p.name.split("_")[0] in GROUPS[group]]
    return [pytest.param(p, id=p.name, marks=() if p.name in FAST else pytest.mark.slow) for p in chosen]


def run_notebook(path: Path, tmp_path: Path):
    """Execute ``path`` in a fresh kernel, working in ``tmp_path``; assert that no cell raised."""
    nb = nbformat.read(path, as_version=4)
    client = NotebookClient(
        nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": tmp_path}}
    )
    client.execute()
    errors = [
        o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", []) if o.output_type == "error"
    ]
    assert not errors
