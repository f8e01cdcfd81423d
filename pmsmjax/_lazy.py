"""Names a package imports on first use (PEP 562), from its ``_LAZY`` table: ``{name: (submodule,
attribute)}``, the submodule relative to the package (``"io.logs"``; a leading dot climbs, as in an import:
``"..assemble"`` from ``pmsmjax.presets`` is ``pmsmjax.assemble``) and the attribute None for the submodule
itself. The packages ``pmsmjax``, [`pmsmjax.presets`][pmsmjax.presets],
[`pmsmjax.controllers`][pmsmjax.controllers] and [`pmsmjax.machines`][pmsmjax.machines] read their re-exports
this way, so that importing them loads no JAX.

Plain Python (importlib and sys only).
"""

import importlib
import sys


def by_module(exports: dict[str, tuple[str, ...]]) -> dict[str, tuple[str, str]]:
    """The ``_LAZY`` table of `exports`, ``{submodule: names it defines}``: each name re-exported under its
    own name."""
    return {name: (module, name) for module, names in exports.items() for name in names}


def lazy_exports(package: str, table: dict[str, tuple[str, str | None]]):
    """The module-level ``(__getattr__, __dir__)`` of `package` (its ``__name__``) re-exporting `table`
    lazily: a name is imported on first use and bound in the package, so the next use is a plain
    attribute."""

    def __getattr__(name):
        if name not in table:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        module, attr = table[name]
        value = importlib.import_module(module if module.startswith(".") else f".{module}", package)
        if attr is not None:
            value = getattr(value, attr)
        setattr(sys.modules[package], name, value)
        return value

    def __dir__():
        return sorted(set(vars(sys.modules[package])) | set(table))

    return __getattr__, __dir__
