"""The ``pmsmjax`` command: ``demo`` (alias ``simulate``), ``replay``, ``tune``, ``bench``, ``pwm-compare``,
``compare``, ``identify``, ``montecarlo`` and ``observe``.

Every subcommand checks its input before compiling anything and writes each output file atomically
(temporary file in the same folder, then rename), so an interrupted or failed run leaves no half file.

Each subcommand is one module of this package with ``add_parser(subparsers)``, which adds its parser and
sets ``func`` to its ``run(args) -> int`` (the exit status); a module imports what its ``run`` needs
inside ``run``, so ``pmsmjax --help`` stays quick. A new subcommand is a new module and its name in
:data:`SUBCOMMANDS`.
"""

import argparse
import importlib
import sys

from ..validation import ParameterError

#: The subcommands' modules, in the order ``pmsmjax --help`` lists them.
SUBCOMMANDS = (
    "demo",
    "replay",
    "bench",
    "tune",
    "pwm_compare",
    "compare",
    "identify",
    "montecarlo",
    "observe",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pmsmjax", description="Differentiable, batched PMSM drive simulation in JAX."
    )
    sub = parser.add_subparsers(dest="command", required=True)
    for name in SUBCOMMANDS:
        importlib.import_module(f"{__name__}.{name}").add_parser(sub)
    return parser


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except ParameterError as err:
        print(f"pmsmjax {args.command}: error: {err}", file=sys.stderr)
        return 2
