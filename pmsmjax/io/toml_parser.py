"""The TOML parser of the running Python, for every reader of TOML files (drive, motor, gains and study
files): the standard library's ``tomllib`` from Python 3.11, else its back-port ``tomli`` (the same API).
Use it as ``from pmsmjax.io.toml_parser import tomllib``, or `read_toml` to read a user's file.
"""

import sys
from pathlib import Path

from pmsmjax.spec.validation import ParameterError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["tomllib", "read_toml"]


def read_toml(path, where: str) -> dict:
    """The TOML file ``path`` as a dict; `where` names it in a refusal (``drive file m.toml``).

    A file an editor saved with a UTF-8 byte-order mark (Windows Notepad does) reads as without one. A file
    that is not UTF-8 text (a binary file), not TOML, or nested too deeply for the parser (arrays in arrays
    thousands deep) is refused with one [`ParameterError`][pmsmjax.spec.validation.ParameterError]."""
    try:
        text = Path(path).read_bytes().decode("utf-8-sig")
    except UnicodeDecodeError as err:
        raise ParameterError(
            f"{where}: not a text file (byte {err.start} is not UTF-8): give the TOML file, saved as UTF-8."
        ) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise ParameterError(f"{where}: not valid TOML ({' '.join(str(err).split())}).") from None
    except RecursionError:
        raise ParameterError(
            f"{where}: not a drive's TOML (its arrays or tables nest too deeply to read): check the file."
        ) from None
