"""Every public name the API reference shows (the packages of ``docs/api/*.md``, their submodules, as
mkdocstrings lists them: names not starting with ``_``) has a docstring: module, function, class, and the
public methods and properties a class defines itself."""

import importlib
import inspect
import pkgutil
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = sorted(
    {
        m
        for page in (ROOT / "docs" / "api").glob("*.md")
        # a ``:::`` block, or the marker from which docs/hooks/api_pages.py lays out a package's pages
        for m in re.findall(r"^(?:::: |<!--\s*api-modules:\s*)([\w.]+)", page.read_text(), re.M)
    }
)


def modules(package: str):
    module = importlib.import_module(package)
    yield module
    for info in pkgutil.walk_packages(getattr(module, "__path__", []), package + "."):
        if not info.name.rsplit(".", 1)[-1].startswith("_"):
            yield importlib.import_module(info.name)


def undocumented(module) -> list[str]:
    missing = [] if (module.__doc__ or "").strip() else [module.__name__]
    for name, obj in vars(module).items():
        if name.startswith("_") or getattr(obj, "__module__", None) != module.__name__:
            continue
        if not (inspect.isfunction(obj) or inspect.isclass(obj)):
            continue
        if not (obj.__doc__ or "").strip():
            missing.append(f"{module.__name__}.{name}")
        if inspect.isclass(obj):
            for attr, member in vars(obj).items():
                if attr.startswith("_"):
                    continue
                target = member.fget if isinstance(member, property) else member
                if inspect.isfunction(target) and not (target.__doc__ or "").strip():
                    # an override documented by the interface it implements is documented
                    inherited = any(
                        (getattr(getattr(base, attr, None), "__doc__", None) or "").strip()
                        for base in obj.__mro__[1:]
                    )
                    if not inherited:
                        missing.append(f"{module.__name__}.{name}.{attr}")
    return missing


def test_the_api_reference_lists_packages():
    assert {"pmsmjax", "pmsmjax.machines", "tuning.identify"} <= set(PACKAGES)


@pytest.mark.parametrize("package", PACKAGES)
def test_every_public_name_has_a_docstring(package):
    missing = sorted({name for module in modules(package) for name in undocumented(module)})
    assert not missing, f"{len(missing)} public names without a docstring: {', '.join(missing)}"
