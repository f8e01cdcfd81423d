"""The user's drive on the command line: ``--motor`` (a preset name or a drive file,
[`pmsmjax.io.drive_files`][pmsmjax.io.drive_files]), ``--u-dc`` and ``--current-limit`` overriding the file's
``[inverter] u_dc_v`` and ``[ratings] max_current_a``, and the scenario flags the user left unset filled from
the file's ``[scenario]``. Every command that runs a drive resolves it here once, in its precheck (pure
Python, before JAX starts), and builds everything after from the
[`DriveSpec`][pmsmjax.io.drive_files.DriveSpec].
"""

from pathlib import Path

from pmsmjax.cli import checks
from pmsmjax.io.drive_files import PRESET_FILES, DriveSpec, drive_spec

__all__ = [
    "DRIVE_FLAGS",
    "U_DC_KNOB",
    "SCENARIO_KEYS",
    "MACHINE_PHASES",
    "add_motor_flag",
    "add_override_flags",
    "scenario_help",
    "resolve_drive",
    "fill_scenario",
    "drive_name",
    "dead_time_entry",
]

#: How messages name the values the flags override (drive_spec's `flags`).
DRIVE_FLAGS = {"u_dc_v": "--u-dc", "max_current_a": "--current-limit"}
#: The DC-link knob a remedy names.
U_DC_KNOB = "--u-dc, or [inverter] u_dc_v in the drive file"
#: The scenario flags (argparse dests) that default to the drive file's ``[scenario]``.
SCENARIO_KEYS = ("speed_rpm", "load_nm", "load_time_s", "duration_s")
#: ``--machine`` -> the drive file's ``n_phases``.
MACHINE_PHASES = {"three-phase": 3, "six-phase": 6, "five-phase": 5}
#: The book drive's scenario, for the help texts (pmsmjax/presets/motors/book.toml).
_BOOK_SCENARIO = {
    "speed_rpm": "1000 r/min",
    "load_nm": "10 N m",
    "load_time_s": "0.2 s",
    "duration_s": "0.4 s",
}


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


def scenario_help(key: str, what: str) -> str:
    """Help text of a scenario flag: what it is, and that it defaults to the drive file's value."""
    return f"{what} (default: the drive file's [scenario] {key}; book: {_BOOK_SCENARIO[key]})"


def resolve_drive(args, n_phases: int = 3) -> DriveSpec:
    """The drive of ``args.motor`` with ``--u-dc``/``--current-limit`` applied (when the command has them),
    checked; a careless value is a one-line [`ParameterError`][pmsmjax.checks.validation.ParameterError]."""
    return drive_spec(
        args.motor,
        n_phases=n_phases,
        u_dc_v=getattr(args, "u_dc", None),
        max_current_a=getattr(args, "current_limit", None),
        check_units=not getattr(args, "trust_units", False),
        flags=DRIVE_FLAGS,
    )


def fill_scenario(args, spec: DriveSpec, keys=SCENARIO_KEYS) -> None:
    """Set each scenario flag of ``keys`` the user left unset (None) to the drive file's ``[scenario]``."""
    for key in keys:
        if getattr(args, key, None) is None:
            setattr(args, key, spec.scenario[key])


def drive_name(spec: DriveSpec) -> str:
    """The drive as titles and the console name it: the preset name, or the drive file's stem."""
    source = spec.source
    return Path(source).stem if source.endswith(".toml") or Path(source).is_file() else source


def dead_time_entry(spec: DriveSpec, drive) -> dict:
    """summary.json's account of the drive file's dead time and device drop: what the bridge that ran
    models (the averaged bridge's period-average error, or the switching bridge's dead windows) and
    whether the controller compensates them."""
    t_d, drop = spec.inverter["dead_time_s"], spec.inverter.get("device_drop_v", 0.0)
    bridge = drive.bridge
    error = getattr(bridge, "voltage_error", None)
    if error is not None:
        modelled, how = float(error.dead_time) > 0.0, "period-averaged by the averaged bridge"
    else:
        modelled, how = (
            getattr(bridge, "resolve_dead_time", False),
            "resolved edge by edge by the switching bridge",
        )
    compensation = getattr(drive.controller, "dead_time_compensation", None)
    entry = {
        "dead_time_s": t_d,
        "device_drop_v": drop,
        "modelled": bool(modelled and t_d > 0.0),
        "compensated": compensation is not None,
    }
    if t_d > 0.0 and modelled:
        entry["how"] = how
    if t_d > 0.0 and not modelled:
        entry["note"] = (
            f"[inverter] dead_time_s = {t_d:g} s is not modelled by this bridge ({type(bridge).__name__}): "
            "the three-phase averaged bridge and the switching bridges model it (six- and five-phase: "
            "--bridge switching)"
        )
    return entry
