"""The drive file: the user's motor, ratings, inverter, sensor and tolerances in one TOML file, read and
checked here for every command, before JAX starts.

Layout (SI units; every table but ``[motor]`` optional)::

    [motor]        R, L_d, L_q, psi_f, pole_pairs, J, B (ohm, H, H, Wb, -, kg m^2, N m s/rad);
                   n_phases = 6 or 5 with L_ls (H) and, five-phase, psi_f3 (Wb); trust_units = true;
                   flux_map = "map.csv" (three-phase: a measured flux map, path relative to the drive
                   file, pmsmjax.io.flux_map_files; L_d, L_q, psi_f then optional)
    [ratings]      rated_speed_rpm, rated_torque_nm or rated_current_a (A peak), max_current_a (A peak)
    [inverter]     u_dc_v, switching_frequency_hz, control_frequency_hz (default: the switching
                   frequency), dead_time_s, device_drop_v (a switch's or diode's on-state voltage, V),
                   dead_time_compensation = true | false (default true: the controller adds the dead
                   time's and drop's predicted error back, as drive firmware does)
    [sensor]       kind = "exact" | "encoder", lines (per mechanical revolution), delay_s
    [tolerances]   relative half-widths of the parameters' spread: R = 0.05 (+-5 %), L_d, L_q, psi_f, J, B,
                   u_dc_v (Monte Carlo draws, robust tuning)
    [control]      current_bandwidth_rad_s, speed_bandwidth_rad_s, startup_current_a,
                   startup_acceleration_rad_s2, handover_speed_rad_s, blend_speed_rad_s
    [scenario]     speed_rpm, load_nm, load_time_s, duration_s (the demo, compare and Monte Carlo run)
    [tuning]       speed_rpm = [low, high], load_nm = [low, high], duration_s = [low, high]

With a flux map the simulated machine is the map's
([`pmsmjax.machines.pmsm_flux_map.PMSMFluxMapdq`][pmsmjax.machines.pmsm_flux_map.PMSMFluxMapdq]) and ``L_d``,
``L_q``, ``psi_f`` are the linear model the design rules and the controller use; left out, they are derived
from the map: ``psi_f = psi_d(0, 0)`` and ``L_d``, ``L_q`` the incremental inductances ``dpsi_d/di_d``,
``dpsi_q/di_q`` at ``i_d = 0``, ``i_q = [ratings] rated_current_a`` when the file gives it, else at zero
current. The rated point is the choice for a map whose q axis saturates: a current loop tuned on the
unsaturated ``L_q`` would run several times faster than designed at rated current, one tuned on the rated
``L_q`` only slower near zero current.

A seven-value motor file (the values at top level or under ``[motor]``) is a drive file with every
other table left out. What a file leaves out is derived from what it gives
([`pmsmjax.presets.drive_ratings`][pmsmjax.presets.drive_ratings] has the rules and their sources) and each
derived value is listed, with how, in [`DriveSpec.derived`][pmsmjax.io.drive_files.DriveSpec]
(``summary.json``'s ``drive_file.derived``).

Checked, each a one-line [`ParameterError`][pmsmjax.checks.validation.ParameterError] naming the file, the
table and key, the value in its unit and the fix: TOML syntax, unknown tables and keys (with the likely meant
one), types, units (an inductance in mH, [`pmsmjax.checks.plausibility`][pmsmjax.checks.plausibility]; a DC
link in kV, a switching frequency in kHz, a dead time in us), a dead time that eats the switching period, a
maximum current below the rated current, a rated torque the maximum current cannot give, and a rated point the
inverter cannot reach (even with field weakening).
"""

import dataclasses
import difflib
import math
import sys
from collections.abc import Mapping
from pathlib import Path

from pmsmjax.analysis.operating_point import reachable, steady_point
from pmsmjax.checks.plausibility import check_motor_units
from pmsmjax.checks.validation import ParameterError, plain
from pmsmjax.presets import drive_ratings as rules

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["DriveSpec", "drive_spec", "read_drive_file", "write_drive_file", "PRESET_FILES", "TABLES"]

MOTOR_FIELDS = ("R", "L_d", "L_q", "psi_f", "pole_pairs", "J", "B")
MULTIPHASE_FIELDS = ("n_phases", "L_ls", "psi_f3")
MOTOR_UNITS = {"R": "ohm", "L_d": "H", "L_q": "H", "psi_f": "Wb", "pole_pairs": "", "J": "kg m^2"}
MOTOR_UNITS.update(B="N m s/rad", L_ls="H", psi_f3="Wb", n_phases="")

#: Every table and its keys with their units (``"int"``: a whole number; ``"str"``: text; ``"range"``: a
#: [low, high] pair).
TABLES = {
    "motor": {**MOTOR_UNITS, "trust_units": "bool", "flux_map": "str"},
    "ratings": {
        "rated_speed_rpm": "r/min",
        "rated_torque_nm": "N m",
        "rated_current_a": "A",
        "max_current_a": "A",
    },  # fmt: skip
    "inverter": {
        "u_dc_v": "V",
        "switching_frequency_hz": "Hz",
        "control_frequency_hz": "Hz",
        "dead_time_s": "s",
        "device_drop_v": "V",
        "dead_time_compensation": "bool",
    },  # fmt: skip
    "sensor": {"kind": "str", "lines": "int", "delay_s": "s"},
    "tolerances": {k: "" for k in ("R", "L_d", "L_q", "psi_f", "J", "B", "L_ls", "u_dc_v")},
    "control": {
        "current_bandwidth_rad_s": "rad/s",
        "speed_bandwidth_rad_s": "rad/s",
        "startup_current_a": "A",
        "startup_acceleration_rad_s2": "rad/s^2",
        "handover_speed_rad_s": "rad/s",
        "blend_speed_rad_s": "rad/s",
    },  # fmt: skip
    "scenario": {"speed_rpm": "r/min", "load_nm": "N m", "load_time_s": "s", "duration_s": "s"},
    "tuning": {"speed_rpm": "range", "load_nm": "range", "duration_s": "range"},
}
SENSOR_KINDS = ("exact", "encoder")
#: Preset names and their drive files in ``pmsmjax/presets/motors/`` (three-phase; the six- and
#: five-phase rewinds of the book motor by ``n_phases``).
PRESET_FOLDER = Path(__file__).resolve().parents[1] / "presets" / "motors"
PRESET_FILES = {
    "book": "book.toml",
    "book_salient": "book_salient.toml",
    "saturated-ipm": "saturated_ipm.toml",
    "servo-400w": "servo_400w_48v.toml",
    "industrial-5k6w": "industrial_5k6w_540v.toml",
    "outer-rotor-24v": "outer_rotor_24v.toml",
}
MULTIPHASE_PRESET_FILES = {
    (6, "book"): "six_phase_book.toml",
    (6, "book_salient"): "six_phase_book_salient.toml",
    (5, "book"): "five_phase_book.toml",
    (5, "book_salient"): "five_phase_book_salient.toml",
}
#: Plausible ranges of the inverter's numbers (wide: they catch a unit slip, not an unusual drive).
DC_LINK_RANGE_V = (5.0, 5000.0)
SWITCHING_RANGE_HZ = (500.0, 1e6)
#: A dead time beyond this share of the switching period is refused (it would take over a fifth of the
#: voltage: a unit slip, us for s).
MAX_DEAD_TIME_SHARE = 0.1
#: A device drop above this (V), or above this share of the DC link, is refused (IGBTs and diodes drop
#: 0.7-3 V, MOSFETs less: more is a unit slip, mV for V, or the drop of a whole string).
MAX_DEVICE_DROP_V = 10.0
MAX_DEVICE_DROP_SHARE = 0.1
MAX_SPEED_RPM = 200_000.0
#: An encoder latency beyond this many control periods is refused (a unit slip: us for s).
MAX_SENSOR_DELAY_PERIODS = 10


@dataclasses.dataclass(frozen=True)
class DriveSpec:
    """A checked drive: the file's tables with every absent value derived.

    - `source`: the preset name or file path;
    - `motor`: SI values (``n_phases`` present only for a multi-phase motor);
    - `ratings`: ``rated_speed_rpm, rated_torque_nm, rated_current_a, max_current_a``;
    - `inverter`: ``u_dc_v, switching_frequency_hz, control_frequency_hz, dead_time_s, device_drop_v``
      and ``dead_time_compensation`` (bool);
    - `sensor`: ``kind`` and, for an encoder, ``lines``, ``delay_s``;
    - `tolerances`: relative half-widths (only those the file gives);
    - `control`, `scenario`, `tuning`: as the file's tables, complete;
    - `derived`: ``{"table.key": how}`` for every value the file left out;
    - `notes`: what a user should know about the drive (a rated point that needs field weakening).
    """

    source: str
    motor: dict
    ratings: dict
    inverter: dict
    sensor: dict
    tolerances: dict
    control: dict
    scenario: dict
    tuning: dict
    derived: dict
    notes: tuple = ()

    @property
    def n_phases(self) -> int:
        """Phase count of the motor: ``[motor] n_phases``, 3 when absent."""
        return int(self.motor.get("n_phases", 3))

    @property
    def Ts(self) -> float:
        """Control period, s."""
        return 1.0 / self.inverter["control_frequency_hz"]

    @property
    def current_limit_a(self) -> float:
        """The controller's peak current limit, A (``[ratings] max_current_a``)."""
        return self.ratings["max_current_a"]

    @property
    def u_dc_v(self) -> float:
        """DC-link voltage, V: ``[inverter] u_dc_v`` (or ``--u-dc``)."""
        return self.inverter["u_dc_v"]

    @property
    def voltage_limit_v(self) -> float:
        """Peak phase voltage of the default modulator's linear range, V."""
        return rules.voltage_limit_v(self.u_dc_v, self.n_phases)

    def summary(self) -> dict:
        """The drive as summary.json reports it (every table, what was derived and how)."""
        return {
            "source": self.source,
            **{t: dict(getattr(self, t)) for t in ("motor", "ratings", "inverter", "sensor", "tolerances")},
            **{t: dict(getattr(self, t)) for t in ("control", "scenario", "tuning")},
            "derived": dict(self.derived),
            "notes": list(self.notes),
        }


def preset_path(name: str, n_phases: int = 3) -> Path | None:
    """The drive file of preset ``name`` for an ``n_phases`` machine, or None."""
    file = PRESET_FILES.get(name) if n_phases == 3 else MULTIPHASE_PRESET_FILES.get((n_phases, name))
    return None if file is None else PRESET_FOLDER / file


def drive_spec(
    name_or_path,
    *,
    n_phases: int = 3,
    u_dc_v: float | None = None,
    max_current_a: float | None = None,
    check_units: bool = True,
    flags: Mapping[str, str] | None = None,
) -> DriveSpec:
    """The drive of a preset name or a drive file, ``u_dc_v`` (V) and ``max_current_a`` (A) overriding
    the file's (``--u-dc``, ``--current-limit``), checked and completed. `flags`: how messages name the
    overrides (``{"u_dc_v": "--u-dc"}``). A preset name unknown for ``n_phases`` phases is refused."""
    key = str(name_or_path)
    path = preset_path(key, n_phases)
    if path is None:
        path = Path(key)
        if not path.is_file():
            names = (
                [n for (k, n) in MULTIPHASE_PRESET_FILES if k == n_phases] if n_phases != 3 else PRESET_FILES
            )
            kind = "is a folder" if path.is_dir() else "does not exist"
            raise ParameterError(
                f"--motor {key}: neither a preset ({', '.join(names)}) nor a drive file (the path {kind}): "
                "give a preset name or the path of a drive TOML file."
            )
        source = key
    else:
        source = key
    overrides = {k: v for k, v in (("u_dc_v", u_dc_v), ("max_current_a", max_current_a)) if v is not None}
    return read_drive_file(
        path, source=source, n_phases=n_phases, check_units=check_units, overrides=overrides, flags=flags
    )


def read_drive_file(
    path,
    *,
    source: str | None = None,
    n_phases: int | None = None,
    check_units: bool = True,
    overrides: Mapping[str, float] | None = None,
    flags: Mapping[str, str] | None = None,
) -> DriveSpec:
    """Read, check and complete the drive file ``path`` (module docstring). `n_phases`: the machine the
    command runs (a file for another is refused); `overrides`: ``u_dc_v``/``max_current_a`` from flags."""
    path = Path(path)
    where = f"drive file {path}"
    if not path.is_file():
        raise ParameterError(f"{where} does not exist: check the path.")
    try:
        data = tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as err:
        raise ParameterError(f"{where}: not valid TOML ({_one_line(err)}).") from err
    tables = _split_tables(data, where)
    for table, values in tables.items():
        _check_keys(table, values, where)
    flux_map_derived = {}
    if "flux_map" in tables["motor"]:
        flux_map_derived = _flux_map_motor(tables["motor"], tables["ratings"], path, where)
    motor = _read_motor(tables["motor"], where, n_phases)
    trust = tables["motor"].get("trust_units", False)
    ratings = _numbers(tables["ratings"], "ratings", where)
    compensation = tables["inverter"].pop("dead_time_compensation", None)
    if compensation is not None and not isinstance(compensation, bool):
        raise ParameterError(
            f"{where}: [inverter] dead_time_compensation must be true or false, got {compensation!r}."
        )
    inverter = _numbers(tables["inverter"], "inverter", where)
    control = _numbers(tables["control"], "control", where)
    scenario = _numbers(tables["scenario"], "scenario", where, positive=("duration_s",), signed=True)
    tolerances = _numbers(tables["tolerances"], "tolerances", where, zero_ok=True)
    if scenario.get("load_time_s", 0.0) < 0.0:
        raise ParameterError(
            f"{where}: [scenario] load_time_s = {plain(scenario['load_time_s'])} s: give a time >= 0 (s "
            "after the start of the run)."
        )
    tuning = _ranges(tables["tuning"], where)
    sensor = _read_sensor(tables["sensor"], where)
    for key, value in (overrides or {}).items():
        table = "inverter" if key == "u_dc_v" else "ratings"
        _positive_number(value, key, (flags or {}).get(key, f"[{table}] {key}"))
        (inverter if table == "inverter" else ratings)[key] = float(value)
    name_of = _namer(where, flags or {}, overrides or {})

    derived = dict(flux_map_derived)
    _complete_inverter(inverter, derived, name_of)
    if compensation is None:
        compensation = True
        derived["inverter.dead_time_compensation"] = (
            "true: the controller adds the dead time's and device drop's predicted error back, as drive "
            "firmware does (it acts when dead_time_s or device_drop_v > 0)"
        )
    inverter["dead_time_compensation"] = compensation
    Ts = 1.0 / inverter["control_frequency_hz"]
    if check_units and not trust:
        check_motor_units(motor, f"{where} [motor]", Ts)
    _complete_ratings(motor, ratings, inverter, derived, name_of)
    notes = _check_rated_point(motor, ratings, inverter, name_of)
    _complete_control(motor, ratings, control, Ts, derived, where)
    if sensor.get("delay_s", 0.0) > MAX_SENSOR_DELAY_PERIODS * Ts:
        raise ParameterError(
            f"{where}: [sensor] delay_s = {plain(sensor['delay_s'])} s is more than "
            f"{MAX_SENSOR_DELAY_PERIODS} "
            f"control periods ({plain(MAX_SENSOR_DELAY_PERIODS * Ts * 1e6)} us): encoder latencies are a few "
            "us, "
            "in s: write e.g. 2e-6 for 2 us."
        )
    if not scenario.keys() >= TABLES["scenario"].keys():
        rule = rules.default_scenario(
            motor, ratings["rated_speed_rpm"], ratings["rated_torque_nm"], ratings["max_current_a"],
            control["speed_bandwidth_rad_s"],
        )  # fmt: skip
        for key, value in rule.items():
            if key not in scenario:
                scenario[key] = value
                derived[f"scenario.{key}"] = _SCENARIO_HOW[key]
    if not scenario["load_time_s"] < scenario["duration_s"]:
        raise ParameterError(
            f"{where}: [scenario] load_time_s = {plain(scenario['load_time_s'])} s is not inside the run "
            f"(duration_s = {plain(scenario['duration_s'])} s): give a load time below the duration."
        )
    if not tuning.keys() >= TABLES["tuning"].keys():
        rule = rules.tuning_ranges(
            motor, ratings["rated_speed_rpm"], ratings["rated_torque_nm"], ratings["max_current_a"],
            inverter["u_dc_v"], control["speed_bandwidth_rad_s"],
        )  # fmt: skip
        for key, value in rule.items():
            if key not in tuning:
                tuning[key] = value
                derived[f"tuning.{key}"] = _TUNING_HOW[key]
    for key, value in tolerances.items():
        if not value < 1.0:
            raise ParameterError(
                f"{where}: [tolerances] {key} = {plain(value)} is a relative half-width and must be below 1 "
                f"(0.05 for +-5 %); a spread of {plain(100 * value)} % would reach zero or below."
            )
    return DriveSpec(
        str(source if source is not None else path), motor, ratings, inverter, sensor, tolerances, control,
        scenario, tuning, derived, tuple(notes),
    )  # fmt: skip


_SCENARIO_HOW = {
    "speed_rpm": "the rated speed",
    "load_nm": f"{rules.DEMO_LOAD_SHARE:g} x the rated torque",
    "load_time_s": "twice the speed loop's settling from rest (full-torque acceleration + 4 / beta), "
    "rounded up to 1, 2, 2.5 or 5 x 10^k s",
    "duration_s": "twice the load time",
}
_TUNING_HOW = {
    "speed_rpm": f"{rules.TUNING_SPEED_SHARES[0]:g} x rated to the lower of "
    f"{rules.TUNING_SPEED_SHARES[1]:g} x rated and the top speed at rated torque (i_d = 0)",
    "load_nm": "0 to the rated torque",
    "duration_s": f"{rules.TUNING_DURATION_FACTORS[0]:g} to {rules.TUNING_DURATION_FACTORS[1]:g} x the "
    "scenario rule's load time at rated speed",
}


def _one_line(text) -> str:
    return " ".join(str(text).split())


def _split_tables(data: dict, where: str) -> dict:
    """``{table: values}`` for every table; a file with no ``[motor]`` table holds its motor at top level
    (the seven-value motor file)."""
    tables = {t: {} for t in TABLES}
    if "motor" in data:
        loose = sorted(k for k, v in data.items() if not isinstance(v, dict))
        if loose:
            raise ParameterError(
                f"{where}: keys {loose} sit outside any table next to a [motor] table: move them into "
                "the table they belong to ([motor], [ratings], [inverter], ...)."
            )
        unknown = sorted(set(data) - set(TABLES))
        if unknown:
            hints = _hints(unknown, TABLES)
            raise ParameterError(
                f"{where}: unknown tables {unknown}{hints}; a drive file has [{'], ['.join(TABLES)}]."
            )
        for table, values in data.items():
            if not isinstance(values, dict):  # pragma: no cover (caught as a loose key above)
                raise ParameterError(f"{where}: [{table}] must be a table.")
            tables[table] = dict(values)
        return tables
    nested = sorted(k for k, v in data.items() if isinstance(v, dict))
    if nested:
        raise ParameterError(
            f"{where}: tables {nested} but no [motor] table: put the motor's values under [motor]."
        )
    tables["motor"] = dict(data)
    return tables


def _hints(unknown, allowed) -> str:
    found = [
        f"{u!r} looks like {m[0]!r}" for u in unknown if (m := difflib.get_close_matches(u, allowed, 1, 0.6))
    ]
    return f" ({'; '.join(found)})" if found else ""


def _check_keys(table: str, values: dict, where: str) -> None:
    unknown = sorted(set(values) - set(TABLES[table]))
    if unknown:
        raise ParameterError(
            f"{where}: unknown keys {unknown} in [{table}]{_hints(unknown, TABLES[table])}; allowed: "
            f"{', '.join(TABLES[table])}."
        )


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _positive_number(value, key: str, name: str, unit: str = "") -> float:
    unit = f" {unit}" if unit else ""
    if not _is_number(value):
        raise ParameterError(f"{name} must be a number{(' of' + unit) if unit else ''}, got {value!r}.")
    if not math.isfinite(value) or value <= 0:
        raise ParameterError(f"{name} = {plain(value)}{unit} must be a finite number above 0.")
    return float(value)


def _numbers(values: dict, table: str, where: str, positive=(), signed=False, zero_ok=False) -> dict:
    """The table's values as floats, each finite and > 0 (>= 0 with `zero_ok` or for a dead time; any
    finite value with `signed`, except the keys of `positive`)."""
    out = {}
    for key, v in values.items():
        unit = TABLES[table][key]
        name = f"{where}: [{table}] {key}"
        if not _is_number(v):
            raise ParameterError(f"{name} must be a number ({unit or 'relative'}), got {v!r}.")
        v = float(v)
        low_ok = (zero_ok or key in ("dead_time_s", "device_drop_v")) and v == 0.0
        if not math.isfinite(v) or ((not signed or key in positive) and v <= 0 and not low_ok):
            need = "a finite number" if signed and key not in positive else "a finite number above 0"
            raise ParameterError(f"{name} = {plain(v)} {unit}: give {need}.")
        out[key] = v
    return out


def _ranges(values: dict, where: str) -> dict:
    out = {}
    for key, v in values.items():
        name = f"{where}: [tuning] {key}"
        if not (isinstance(v, list) and len(v) == 2 and all(_is_number(x) and math.isfinite(x) for x in v)):
            raise ParameterError(f"{name} must be [low, high], two finite numbers, got {v!r}.")
        low, high = (float(x) for x in v)
        if not 0 <= low <= high or (key == "duration_s" and low <= 0):
            raise ParameterError(
                f"{name} = [{plain(low)}, {plain(high)}]: give 0 <= low <= high (durations > 0)."
            )
        out[key] = [low, high]
    return out


#: The linear-model values a flux map stands in for.
FLUX_MAP_DERIVES = ("L_d", "L_q", "psi_f")


def _flux_map_motor(values: dict, ratings: dict, path: Path, where: str) -> dict:
    """Read ``[motor] flux_map`` and put the map's linear model (module docstring) into ``values`` where the
    file leaves it out; the map's absolute path replaces the relative one. Returns the derivation notes."""
    from pmsmjax.io.flux_map_files import read_flux_map

    name = values["flux_map"]
    if not isinstance(name, str) or not name:
        raise ParameterError(f'{where}: [motor] flux_map must be a file name (e.g. "map.csv"), got {name!r}.')
    if values.get("n_phases", 3) != 3:
        raise ParameterError(
            f"{where}: [motor] flux_map is for a three-phase motor: drop n_phases or the map."
        )
    map_path = Path(name) if Path(name).is_absolute() else path.resolve().parent / name
    if not map_path.is_file():
        raise ParameterError(
            f"{where}: [motor] flux_map = {name!r}: {map_path} does not exist (the path is relative to the "
            "drive file's folder)."
        )
    grid = read_flux_map(map_path)
    current = ratings.get("rated_current_a", 0.0)
    if not isinstance(current, (int, float)) or isinstance(current, bool):
        current = 0.0  # refused with its own message when [ratings] is read
    at = f"i_d = 0, i_q = {current:g} A (the rated current)" if current else "zero current"
    linear = grid.linear_model(float(current))
    how = {
        "psi_f": "psi_d(0, 0) of the flux map",
        "L_d": f"the flux map's incremental dpsi_d/di_d at {at}",
        "L_q": f"the flux map's incremental dpsi_q/di_q at {at}",
    }
    derived = {}
    for key in FLUX_MAP_DERIVES:
        if key not in values:
            values[key] = linear[key]
            derived[f"motor.{key}"] = how[key]
    values["flux_map"] = str(map_path)
    return derived


def _read_motor(values: dict, where: str, n_phases: int | None) -> dict:
    trust = values.get("trust_units", False)
    if not isinstance(trust, bool):
        raise ParameterError(f"{where}: [motor] trust_units must be true or false, got {trust!r}.")
    file_phases = values.get("n_phases", 3)
    if not isinstance(file_phases, int) or isinstance(file_phases, bool) or file_phases not in (3, 5, 6):
        raise ParameterError(f"{where}: [motor] n_phases = {file_phases!r}: give 3, 5 or 6.")
    if n_phases is not None and file_phases != n_phases:
        word = {3: "three", 5: "five", 6: "six"}
        raise ParameterError(
            f"{where}: a {word[file_phases]}-phase motor (n_phases = {file_phases}); this command runs a "
            f"{word[n_phases]}-phase machine: give --machine {word[file_phases]}-phase or a "
            f"{word[n_phases]}-phase drive file."
        )
    needed = MOTOR_FIELDS + (("L_ls",) if file_phases != 3 else ())
    missing = [f for f in needed if f not in values]
    if missing:
        raise ParameterError(
            f"{where} lacks {', '.join(missing)} in [motor]: it needs {', '.join(needed)} (SI units: "
            f"{', '.join(k + ' ' + (MOTOR_UNITS[k] or '-') for k in needed)})."
        )
    extra = sorted(k for k in ("L_ls", "psi_f3") if k in values and file_phases == 3)
    if extra or ("psi_f3" in values and file_phases != 5):
        raise ParameterError(
            f"{where}: [motor] {', '.join(extra or ['psi_f3'])} belong to a multi-phase motor (L_ls: "
            "five- or six-phase, psi_f3: five-phase): set n_phases or drop them."
        )
    motor = {"flux_map": values["flux_map"]} if "flux_map" in values else {}
    for key in needed + tuple(k for k in ("psi_f3",) if k in values):
        v = values[key]
        if key == "pole_pairs":
            if not isinstance(v, int) or isinstance(v, bool) or v < 1:
                raise ParameterError(f"{where}: [motor] pole_pairs must be a whole number >= 1, got {v!r}.")
            motor[key] = v
            continue
        if not _is_number(v) or not math.isfinite(v):
            raise ParameterError(
                f"{where}: [motor] {key} must be a finite number ({MOTOR_UNITS[key]}), got {v!r}."
            )
        lowest_ok = key in ("B", "psi_f3")
        if v < 0 or (v == 0 and not lowest_ok):
            need = ">= 0" if lowest_ok else "> 0"
            raise ParameterError(
                f"{where}: [motor] {key} = {plain(v)} {MOTOR_UNITS[key]}: give a value {need}."
            )
        motor[key] = float(v)
    if file_phases != 3:
        motor["n_phases"] = file_phases
    return motor


def _read_sensor(values: dict, where: str) -> dict:
    kind = values.get("kind", "exact")
    if kind not in SENSOR_KINDS:
        raise ParameterError(f"{where}: [sensor] kind = {kind!r}: give one of {', '.join(SENSOR_KINDS)}.")
    sensor = {"kind": kind}
    if kind == "exact":
        extra = sorted(set(values) - {"kind"})
        if extra:
            raise ParameterError(f'{where}: [sensor] {", ".join(extra)} apply to kind = "encoder" only.')
        return sensor
    lines = values.get("lines")
    if not isinstance(lines, int) or isinstance(lines, bool) or lines < 1:
        raise ParameterError(
            f"{where}: [sensor] lines must be the encoder's lines per revolution, a whole number >= 1 "
            f"(e.g. 2500), got {lines!r}."
        )
    sensor["lines"] = lines
    delay = values.get("delay_s", 0.0)
    if not _is_number(delay) or not math.isfinite(delay) or delay < 0:
        raise ParameterError(f"{where}: [sensor] delay_s must be a number >= 0 (s), got {delay!r}.")
    sensor["delay_s"] = float(delay)
    return sensor


def _namer(where: str, flags: Mapping[str, str], overrides: Mapping[str, float]):
    """How a message names a value: the flag that set it, else the file's table and key."""
    table_of = {
        key: table for table, keys in TABLES.items() for key in keys if table in ("ratings", "inverter")
    }

    def name_of(key: str) -> str:
        if key in overrides and key in flags:
            return flags[key]
        return f"{where}: [{table_of[key]}] {key}"

    return name_of


def _complete_inverter(inverter: dict, derived: dict, name_of) -> None:
    u_dc = inverter.get("u_dc_v")
    if u_dc is not None and not DC_LINK_RANGE_V[0] <= u_dc <= DC_LINK_RANGE_V[1]:
        hint = f": it looks like kV: write {plain(u_dc * 1e3)}" if u_dc * 1e3 <= DC_LINK_RANGE_V[1] else ""
        raise ParameterError(
            f"{name_of('u_dc_v')} = {plain(u_dc)} V is outside the {plain(DC_LINK_RANGE_V[0])}-"
            f"{plain(DC_LINK_RANGE_V[1])} V of drive DC links{hint} (V)."
        )
    for key in ("switching_frequency_hz", "control_frequency_hz"):
        f = inverter.get(key)
        if f is not None and not SWITCHING_RANGE_HZ[0] <= f <= SWITCHING_RANGE_HZ[1]:
            hint = f": it looks like kHz: write {plain(f * 1e3)}" if f * 1e3 <= SWITCHING_RANGE_HZ[1] else ""
            raise ParameterError(
                f"{name_of(key)} = {plain(f)} Hz is outside the {plain(SWITCHING_RANGE_HZ[0])} Hz-"
                f"{plain(SWITCHING_RANGE_HZ[1] / 1e3)} kHz of drive inverters{hint} (Hz)."
            )
    if "switching_frequency_hz" not in inverter:
        inverter["switching_frequency_hz"] = 10_000.0
        derived["inverter.switching_frequency_hz"] = (
            "the book's 10 kHz (no [inverter] switching_frequency_hz)"
        )
    if "control_frequency_hz" not in inverter:
        inverter["control_frequency_hz"] = inverter["switching_frequency_hz"]
        derived["inverter.control_frequency_hz"] = "the switching frequency (one update per PWM period)"
    f_sw, f_c = inverter["switching_frequency_hz"], inverter["control_frequency_hz"]
    if not f_sw / 10.0 <= f_c <= 2.0 * f_sw:
        raise ParameterError(
            f"{name_of('control_frequency_hz')} = {plain(f_c)} Hz: the control runs once or twice per PWM "
            f"period ({plain(f_sw)} Hz), or at most 10 periods apart; give {plain(f_sw)} or "
            f"{plain(2 * f_sw)}."
        )
    period = 1.0 / f_sw
    t_d = inverter.get("dead_time_s", 0.0)
    if "dead_time_s" not in inverter:
        inverter["dead_time_s"] = 0.0
        derived["inverter.dead_time_s"] = "0 (ideal switches)"
    if t_d > MAX_DEAD_TIME_SHARE * period:
        longer = "longer than" if t_d >= period else f"{100 * t_d / period:.0f} % of"
        raise ParameterError(
            f"{name_of('dead_time_s')} = {plain(t_d)} s is {longer} the {plain(period * 1e6)} us switching "
            f"period ({plain(f_sw / 1e3)} kHz): dead times are 0.1-5 us, in s: write e.g. 2e-6 for 2 us."
        )
    if "device_drop_v" not in inverter:
        inverter["device_drop_v"] = 0.0
        derived["inverter.device_drop_v"] = "0 (ideal switches)"
    drop, u_dc = inverter["device_drop_v"], inverter.get("u_dc_v")
    if drop > MAX_DEVICE_DROP_V or (u_dc is not None and drop > MAX_DEVICE_DROP_SHARE * u_dc):
        of_link = f" or {100 * MAX_DEVICE_DROP_SHARE:g} % of the {plain(u_dc)} V DC link" if u_dc else ""
        raise ParameterError(
            f"{name_of('device_drop_v')} = {plain(drop)} V is above {plain(MAX_DEVICE_DROP_V)} V{of_link}: a "
            "switch or diode drops 0.7-3 V (MOSFETs less), in V: write e.g. 1.5."
        )


def _complete_ratings(motor: dict, ratings: dict, inverter: dict, derived: dict, name_of) -> None:
    speed = ratings.get("rated_speed_rpm")
    if speed is not None and speed > MAX_SPEED_RPM:
        raise ParameterError(
            f"{name_of('rated_speed_rpm')} = {plain(speed)} r/min: give at most {plain(MAX_SPEED_RPM)}."
        )
    torque, current, peak = (ratings.get(k) for k in ("rated_torque_nm", "rated_current_a", "max_current_a"))
    if torque is not None and current is not None:
        can = rules.torque_at_current(motor, current)
        if torque > 1.05 * can:
            raise ParameterError(
                f"{name_of('rated_torque_nm')} = {plain(torque)} N m is more than rated_current_a = "
                f"{plain(current)} A gives ({can:.3g} N m with psi_f = {plain(motor['psi_f'])} Wb, "
                f"{motor['pole_pairs']} pole pairs): the ratings contradict each other; check psi_f (peak "
                "flux per phase, Wb) and the current (A peak, not RMS), or give only one of them."
            )
    elif torque is not None:
        ratings["rated_current_a"] = rules.current_for_torque(motor, torque)
        derived["ratings.rated_current_a"] = "the MTPA current of the rated torque"
    elif current is not None:
        ratings["rated_torque_nm"] = rules.torque_at_current(motor, current)
        derived["ratings.rated_torque_nm"] = "the MTPA torque of the rated current"
    elif peak is not None:
        ratings["rated_current_a"] = peak / rules.PEAK_TO_RATED_CURRENT
        ratings["rated_torque_nm"] = rules.torque_at_current(motor, ratings["rated_current_a"])
        derived["ratings.rated_current_a"] = f"max_current_a / {rules.PEAK_TO_RATED_CURRENT:g}"
        derived["ratings.rated_torque_nm"] = "the MTPA torque of the rated current"
    else:
        # Nothing about the current: take the book drive's ratio of rated current to the characteristic
        # current psi_f / L_d (9.1 A of 34.8 A) and say so loudly.
        ratings["rated_current_a"] = 0.26 * motor["psi_f"] / motor["L_d"]
        ratings["rated_torque_nm"] = rules.torque_at_current(motor, ratings["rated_current_a"])
        derived["ratings.rated_current_a"] = (
            "0.26 x the characteristic current psi_f / L_d (the book drive's ratio): a guess; give "
            "[ratings] rated_torque_nm or rated_current_a"
        )
        derived["ratings.rated_torque_nm"] = "the MTPA torque of the rated current"
    if peak is None:
        ratings["max_current_a"] = rules.PEAK_TO_RATED_CURRENT * ratings["rated_current_a"]
        derived["ratings.max_current_a"] = f"{rules.PEAK_TO_RATED_CURRENT:g} x the rated current"
    elif peak < ratings["rated_current_a"] * (1.0 - 1e-9):
        given = (
            "rated_current_a"
            if current is not None
            else f"the {plain(ratings['rated_torque_nm'])} N m rated torque's"
        )
        raise ParameterError(
            f"{name_of('max_current_a')} = {plain(peak)} A is below {given} "
            f"{ratings['rated_current_a']:.3g} A: "
            "the peak current must be at least the rated current (both A peak); raise max_current_a or "
            "lower the rating."
        )
    u_limit = None
    if "u_dc_v" not in inverter:
        if speed is None:
            inverter["u_dc_v"] = 311.0
            derived["inverter.u_dc_v"] = "the book's 311 V (rectified 220 V mains): give [inverter] u_dc_v"
        else:
            need = rules.rated_point_voltage_v(motor, speed, ratings["rated_torque_nm"])
            inverter["u_dc_v"] = math.ceil(1.1 * need / rules.voltage_limit_v(1.0, motor.get("n_phases", 3)))
            derived["inverter.u_dc_v"] = "the rated point's voltage with 10 % margin (no [inverter] u_dc_v)"
    u_limit = rules.voltage_limit_v(inverter["u_dc_v"], motor.get("n_phases", 3))
    if speed is None:
        ratings["rated_speed_rpm"] = round(
            rules.base_speed_rpm(motor, ratings["rated_torque_nm"], u_limit), 1
        )
        derived["ratings.rated_speed_rpm"] = (
            f"the base speed: the rated torque's MTPA point at {100 * rules.BASE_SPEED_VOLTAGE_SHARE:g} % of "
            "the voltage limit"
        )
        if ratings["rated_speed_rpm"] <= 0:
            raise ParameterError(
                f"{name_of('u_dc_v')} = {plain(inverter['u_dc_v'])} V cannot drive the rated current "
                f"{ratings['rated_current_a']:.3g} A through R = {plain(motor['R'])} ohm even at standstill: "
                "raise u_dc_v or check R (ohm) and the current (A peak)."
            )


def _check_rated_point(motor: dict, ratings: dict, inverter: dict, name_of) -> list:
    """Refuse a rated point the inverter cannot reach within the maximum current, even with field
    weakening; a point that needs field weakening is kept with a note."""
    n = motor.get("n_phases", 3)
    u_limit = rules.voltage_limit_v(inverter["u_dc_v"], n)
    speed, torque = ratings["rated_speed_rpm"], ratings["rated_torque_nm"]
    need = rules.rated_point_voltage_v(motor, speed, torque)
    if need <= u_limit:
        return []
    fw = reachable(motor, speed, torque, u_limit, ratings["max_current_a"], field_weakening=True)
    if fw["ok"]:
        # reachable() gives the i_d of least voltage; the note gives the weakest field weakening that
        # suffices (the voltage falls monotonically from i_d = 0 to that point: bisection).
        enough, short = fw["i_d"], 0.0
        for _ in range(60):
            mid = 0.5 * (enough + short)
            if steady_point(motor, speed * rules.RPM, torque, mid)["voltage"] <= u_limit:
                enough = mid
            else:
                short = mid
        return [
            f"the rated point ({plain(speed)} r/min, {torque:.3g} N m) needs {need:.0f} V with MTPA, above "
            f"the {u_limit:.0f} V the inverter gives: it is reached with field weakening only (i_d = "
            f"{enough:.3g} A at least); run demo with --field-weakening"
        ]
    top = rules.base_speed_rpm(motor, torque, u_limit, voltage_share=1.0)
    u_need = math.ceil(need / rules.voltage_limit_v(1.0, n))
    raise ParameterError(
        f"{name_of('rated_speed_rpm')} = {plain(speed)} r/min at {torque:.3g} N m needs {need:.0f} V peak "
        f"per phase, and the inverter's u_dc_v = {plain(inverter['u_dc_v'])} V gives {u_limit:.0f} V (field "
        f"weakening within max_current_a = {plain(ratings['max_current_a'])} A does not close the gap): "
        f"raise u_dc_v to at least {u_need} V, or lower rated_speed_rpm to about {top:.0f} r/min."
    )


def _complete_control(
    motor: dict, ratings: dict, control: dict, Ts: float, derived: dict, where: str
) -> None:
    given = control.get("current_bandwidth_rad_s")
    unstable = rules.current_bandwidth_rule(Ts, phase_margin_deg=0.0)
    if given is not None and given >= unstable:
        raise ParameterError(
            f"{where}: [control] current_bandwidth_rad_s = {plain(given)} rad/s leaves the current loop no "
            "phase "
            f"margin against its 1.5-period delay at {plain(1 / Ts)} Hz (it must stay below {unstable:.0f} "
            f"rad/s; the design rule gives {rules.current_bandwidth_rule(Ts):.0f}): check the unit (rad/s, "
            "not Hz x 1000) or leave it out."
        )
    if "current_bandwidth_rad_s" not in control:
        control["current_bandwidth_rad_s"] = rules.current_bandwidth_rule(Ts)
        derived["control.current_bandwidth_rad_s"] = (
            f"{rules.CURRENT_LOOP_PHASE_MARGIN_DEG:g} deg phase margin against the 1.5-period loop delay: "
            "(pi/2 - 65 deg) / (1.5 Ts)"
        )
    if "speed_bandwidth_rad_s" not in control:
        control["speed_bandwidth_rad_s"] = rules.speed_bandwidth_rule(
            motor, control["current_bandwidth_rad_s"], ratings["max_current_a"], ratings["rated_speed_rpm"]
        )
        derived["control.speed_bandwidth_rad_s"] = (
            "a step of a fifth of the rated speed reaches the current limit with the P part alone: "
            "k_t I_max / (J w_rated / 5), at most a tenth of the current loop's"
        )
    if not control["speed_bandwidth_rad_s"] < control["current_bandwidth_rad_s"]:
        raise ParameterError(
            f"{where}: [control] speed_bandwidth_rad_s = {plain(control['speed_bandwidth_rad_s'])} rad/s is "
            "not "
            f"below the current loop's {control['current_bandwidth_rad_s']:.0f} rad/s: a cascade needs the "
            "speed "
            "loop well inside the current loop (a tenth is usual); lower it or leave it out."
        )
    startup = rules.startup_rule(motor, ratings)
    for key, value in startup.items():
        if key not in control:
            control[key] = value
            derived[f"control.{key}"] = rules.STARTUP_HOW[key]


def write_drive_file(path, tables: Mapping[str, Mapping], header: str = "", comments: Mapping | None = None):
    """Write ``tables`` (``{"motor": {...}, "tolerances": {...}, ...}``, the layout of the module
    docstring) as a drive file, atomically; `comments`: ``{"table.key": text}`` written after a value.
    Numbers keep their full precision (``repr``)."""
    from pmsmjax.io.logs import atomic_write

    comments = comments or {}
    lines = [f"# {line}" for line in header.splitlines()] + ([""] if header else [])
    for table in TABLES:
        values = tables.get(table)
        if not values:
            continue
        lines.append(f"[{table}]")
        for key, value in values.items():
            if isinstance(value, bool):
                text = "true" if value else "false"
            elif isinstance(value, str):
                text = f'"{value}"'
            elif isinstance(value, (list, tuple)):
                text = "[" + ", ".join(repr(float(v)) for v in value) + "]"
            elif isinstance(value, int):
                text = str(value)
            else:
                text = repr(float(value))
            note = comments.get(f"{table}.{key}")
            lines.append(f"{key} = {text}" + (f"  # {note}" if note else ""))
        lines.append("")
    text = "\n".join(lines)
    tomllib.loads(text)  # what is written must read back
    return atomic_write(path, lambda f: f.write(text), mode="w")
