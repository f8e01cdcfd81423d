"""The TOML parser of the running Python, for every reader of TOML files (drive, motor, gains and study
files): the standard library's ``tomllib`` from Python 3.11, else its back-port ``tomli`` (the same API).
Use it as ``from pmsmjax.io.toml_parser import tomllib``.
"""

import sys

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["tomllib"]
