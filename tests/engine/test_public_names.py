"""The public names survive the package's layout: every name ``pmsmjax`` exports, and every dotted
``pmsmjax.X.Y`` the README's Python examples use, resolves to a real object."""

import importlib
import re
from pathlib import Path

import pytest

import pmsmjax

README = Path(__file__).resolve().parents[2] / "README.md"


def _resolve(dotted: str):
    """The object ``a.b.c`` names: the longest importable module prefix, then attributes."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ModuleNotFoundError:
            continue
        for name in parts[cut:]:
            obj = getattr(obj, name)
        return obj
    raise ModuleNotFoundError(dotted)


@pytest.mark.parametrize("name", pmsmjax.__all__)
def test_exported_name_resolves(name):
    assert getattr(pmsmjax, name) is not None
    assert name in dir(pmsmjax)


def test_simulate_is_the_function_even_after_its_module_is_imported():
    importlib.import_module("pmsmjax.simulate")
    assert callable(pmsmjax.simulate) and pmsmjax.simulate.__name__ == "simulate"


def test_readme_python_names_resolve():
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    names = sorted({m for b in blocks for m in re.findall(r"\bpmsmjax(?:\.\w+)+", b)})
    assert names, "the README shows no pmsmjax name"
    for dotted in names:
        assert _resolve(dotted) is not None, dotted


def test_unknown_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'nonexistent'"):
        pmsmjax.nonexistent  # noqa: B018
