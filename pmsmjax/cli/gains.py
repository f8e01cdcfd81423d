"""``--gains FILE`` for every command that builds a drive: the gains ``pmsmjax tune`` wrote (its
``gains.toml``: a ``[gains]`` table of ``"dotted.name" = value``, SI units) replace the design-rule gains.

`add_gains_flag` adds the flag; `read_gains_flag` reads and checks the file before any work
(pure Python); `apply_gains_flag` sets the gains on a built drive, refusing names the drive does not
have (gains tuned for another control) with the names it does have.
"""

import math
from pathlib import Path

from pmsmjax.io.toml_parser import read_toml
from pmsmjax.spec.validation import ParameterError

__all__ = ["add_gains_flag", "read_gains_flag", "apply_gains_flag"]


def add_gains_flag(p) -> None:
    """Add ``--gains FILE`` (a gains.toml written by ``pmsmjax tune``) to the subcommand parser `p`."""
    p.add_argument(
        "--gains",
        metavar="FILE",
        default=None,
        help="gains TOML written by pmsmjax tune (its gains.toml) to use instead of the design-rule gains "
        "(default: design rules)",
    )


def read_gains_flag(path, flag: str = "--gains") -> dict[str, float] | None:
    """``{name: value}`` from a gains file, or None when ``path`` is None; checked before any work."""
    if path is None:
        return None
    path = Path(path)
    if not path.is_file():
        state = "is a folder" if path.is_dir() else "does not exist"
        raise ParameterError(f"{flag} {path}: the file {state}; give the gains.toml pmsmjax tune wrote.")
    data = read_toml(path, f"{flag} {path}")
    table = data.get("gains")
    if not isinstance(table, dict) or not table:
        raise ParameterError(
            f"{flag} {path}: no [gains] table; give the gains.toml pmsmjax tune wrote "
            '([gains] with lines like "controller.speed.kp" = 0.1).'
        )
    out = {}
    for name, value in table.items():
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ParameterError(
                f"{flag} {path}: gain {name!r} = {value!r} is not a finite number{_quoted(value)}."
            )
        if value <= 0:
            raise ParameterError(
                f"{flag} {path}: gain {name!r} = {value!r} must be > 0 (gains are positive)."
            )
        out[name] = float(value)
    return out


def _quoted(value) -> str:
    return " (a string: write the number without quotes)" if isinstance(value, str) else ""


def apply_gains_flag(drive, gains: dict | None, control: str, flag: str = "--gains"):
    """``drive`` with ``gains`` set (unchanged for None); a name the drive lacks is refused."""
    if gains is None:
        return drive
    from tuning.parameters import apply_gains, array_leaf_names, check_gains

    have = set(array_leaf_names(drive))
    foreign = [n for n in gains if n not in have]
    if foreign:
        own = sorted(n for n in have if n.startswith("controller."))
        raise ParameterError(
            f"{flag}: {', '.join(foreign)} is not a gain of the {control} drive (the file was tuned for "
            f"another control method?): give the gains of --control {control} ({', '.join(own)})."
        )
    check_gains(drive, gains, flag)
    return apply_gains(drive, gains)
