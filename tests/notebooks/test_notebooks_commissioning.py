"""Notebooks of notebooks/ executed top to bottom without error: those of notebook_run.GROUPS for this
file (a file of its own so that ``--dist loadfile`` runs it beside the other notebooks)."""

import pytest
from notebook_run import cases, run_notebook


@pytest.mark.parametrize("path", cases("test_notebooks_commissioning.py"))
def test_notebook_runs(path, tmp_path):
    run_notebook(path, tmp_path)
