"""The user's drive on the command line: ``--motor`` (a preset name or a drive file,
[`pmsmjax.io.drive_files`][pmsmjax.io.drive_files]), ``--u-dc`` and ``--current-limit`` overriding the file's
``[inverter] u_dc_v`` and ``[ratings] max_current_a``, and the scenario flags the user left unset filled from
the file's ``[scenario]``. Every command that runs a drive resolves it here once, in its precheck (pure
Python, before JAX starts), and builds everything after from the
[`DriveSpec`][pmsmjax.spec.drive_spec.DriveSpec].
"""

from pathlib import Path

from pmsmjax.cli import checks
from pmsmjax.io.drive_files import PRESET_FILES, drive_spec
from pmsmjax.spec.drive_spec import DriveSpec

__all__ = [
    "DRIVE_FLAGS",
    "U_DC_KNOB",
    "SCENARIO_KEYS",
    "MACHINE_PHASES",
    "add_drive_flags",
    "add_motor_flag",
    "add_override_flags",
    "add_trust_units_flag",
    "add_scenario_flags",
    "add_logged_motor_flags",
    "scenario_help",
    "resolve_drive",
    "fill_scenario",
    "scenario_name",
    "drive_name",
]

#: How messages name the values the flags override (drive_spec's `flags`).
DRIVE_FLAGS = {"u_dc_v": "--u-dc", "max_current_a": "--current-limit"}
#: The DC-link knob a remedy names.
U_DC_KNOB = "--u-dc, or [inverter] u_dc_v in the drive file"
#: The scenario flags (argparse dests) that default to the drive file's ``[scenario]``.
SCENARIO_KEYS = ("speed_rpm", "load_nm", "load_time_s", "duration_s")
#: ``--machine`` -> the drive file's ``n_phases``.
MACHINE_PHASES = {"three-phase": 3, "six-phase": 6, "five-phase": 5}
#: What the help of each scenario flag calls it.
_SCENARIO_WHAT = {
    "speed_rpm": "speed step, r/min",
    "load_nm": "load step, N m",
    "load_time_s": "time of the load step, s",
    "duration_s": "simulated time, s",
}
#: The book drive's scenario, for the help texts (pmsmjax/presets/motors/book.toml).
_BOOK_SCENARIO = {
    "speed_rpm": "1000 r/min",
    "load_nm": "10 N m",
    "load_time_s": "0.2 s",
    "duration_s": "0.4 s",
}


def add_drive_flags(p, out: str, motor: str | None = "book", motor_text: str | None = None) -> None:
    """The flags every command that runs the user's drive opens with: ``--out`` (default `out`),
    ``--motor`` (default `motor`, said as `motor_text`, `add_motor_flag`) and the overrides
    ``--u-dc``, ``--current-limit``."""
    checks.add_out_flag(p, out)
    add_motor_flag(p, motor, motor_text)
    add_override_flags(p)


def add_motor_flag(p, default: str | None = "book", default_text: str | None = None) -> None:
    """``--motor``: a preset name or a drive file; `default_text` says the default when it is not
    simply `default`."""
    p.add_argument(
        "--motor",
        default=default,
        help=f"the drive: a preset name ({', '.join(PRESET_FILES)}; with --machine six-phase or five-phase "
        "the book motor's rewinds book, book_salient) or a drive TOML file ([motor], [ratings], [inverter], "
        "[sensor], [control], [scenario], ...; a seven-value motor file is one)"
        + f" (default {default_text or default})",
    )


def add_override_flags(p, current_limit: bool = True) -> None:
    """``--u-dc`` and ``--current-limit``: override the drive file's DC link and current limit."""
    p.add_argument(
        "--u-dc",
        type=checks.positive("V"),
        default=None,
        help="DC-link voltage, V (default: the drive file's [inverter] u_dc_v; book: 311)",
    )
    if current_limit:
        p.add_argument(
            "--current-limit",
            type=checks.positive("A"),
            default=None,
            help="peak phase-current limit, A (default: the drive file's [ratings] max_current_a; book: 15)",
        )


def add_trust_units_flag(p, help: str = "accept motor values outside the plausible ranges") -> None:
    """``--trust-units``: skip the drive file's unit plausibility check (`resolve_drive`)."""
    p.add_argument("--trust-units", action="store_true", help=help)


def add_logged_motor_flags(p, role: str) -> None:
    """The log file and ``--motor`` (its `role`, required) of a command that runs a model on a logged drive
    run."""
    p.add_argument("log", help="log file (.csv, .npz or .mat)")
    p.add_argument(
        "--motor",
        required=True,
        help=f"{role}: a preset name (book, book_salient, servo-400w, ...) or a drive TOML file (its "
        "[motor]; a seven-value motor file is one)",
    )


def add_scenario_flags(p, keys=SCENARIO_KEYS, types=None, whats=None) -> None:
    """The scenario flags of `keys` (argparse dests of `SCENARIO_KEYS`), each defaulting to the
    drive file's ``[scenario]`` (`fill_scenario`): a finite speed and load, a load time >= 0 and a
    duration > 0, unless `types` (dest -> argparse ``type``) checks more; `whats` (dest -> text): what
    the help calls a flag whose meaning is narrower than a step's."""
    types = {
        "speed_rpm": checks.real("r/min"),
        "load_nm": checks.real("N m"),
        "load_time_s": checks.nonnegative("s"),
        "duration_s": checks.positive("s"),
        **(types or {}),
    }
    whats = {**_SCENARIO_WHAT, **(whats or {})}
    for key in keys:
        p.add_argument(checks.flag(key), type=types[key], help=scenario_help(key, whats[key]))


def scenario_help(key: str, what: str) -> str:
    """Help text of a scenario flag: what it is, and that it defaults to the drive file's value."""
    return f"{what} (default: the drive file's [scenario] {key}; book: {_BOOK_SCENARIO[key]})"


def resolve_drive(args, n_phases: int = 3) -> DriveSpec:
    """The drive of ``args.motor`` with ``--u-dc``/``--current-limit`` applied (when the command has them),
    checked; a careless value is a one-line [`ParameterError`][pmsmjax.spec.validation.ParameterError]."""
    return drive_spec(
        args.motor,
        n_phases=n_phases,
        u_dc_v=getattr(args, "u_dc", None),
        max_current_a=getattr(args, "current_limit", None),
        check_units=not getattr(args, "trust_units", False),
        flags=DRIVE_FLAGS,
    )


def fill_scenario(args, spec: DriveSpec, keys=SCENARIO_KEYS) -> None:
    """Set each scenario flag of ``keys`` the user left unset (None) to the drive file's ``[scenario]``;
    `scenario_name` then names such a value by its field in the file, not by a flag never given."""
    filled = dict(getattr(args, "scenario_from_file", {}))
    for key in keys:
        if getattr(args, key, None) is None:
            setattr(args, key, spec.scenario[key])
            filled[key] = f"drive file {spec.source}: [scenario] {key} ="
    args.scenario_from_file = filled


def scenario_name(args, key: str) -> str:
    """How a message names the scenario value ``key``: its flag, or the drive file's field it came from
    (`fill_scenario`)."""
    return getattr(args, "scenario_from_file", {}).get(key) or checks.flag(key)


def drive_name(spec: DriveSpec) -> str:
    """The drive as titles and the console name it: the preset name, or the drive file's stem."""
    source = spec.source
    return Path(source).stem if source.endswith(".toml") or Path(source).is_file() else source
