"""Every notebook in notebooks/ executes top to bottom without error.

The book's FOC demo notebook is in the fast tier; the others each compile tens of programs (20-35 s on 2
cores) and run in the whole suite. This file runs notebooks 01-05; the other test files of this folder
run the rest (notebook_run.GROUPS), so that the workers share them."""

from pathlib import Path

import pytest
from notebook_run import FAST, GROUPS, NOTEBOOKS, cases, run_notebook


def test_there_are_notebooks():
    assert NOTEBOOKS, "notebooks/ holds no notebook"
    assert FAST <= {p.name for p in NOTEBOOKS}, "a fast-tier notebook is missing"
    # every notebook is run by exactly one test file, and each test file named runs one
    prefixes = [p.name.split("_")[0] for p in NOTEBOOKS]
    assigned = [n for names in GROUPS.values() for n in names]
    assert sorted(assigned) == sorted(prefixes), (assigned, prefixes)
    assert all((Path(__file__).parent / name).is_file() for name in GROUPS)


@pytest.mark.parametrize("path", cases("test_notebooks.py"))
def test_notebook_runs(path, tmp_path):
    run_notebook(path, tmp_path)
