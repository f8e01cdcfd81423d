"""The drive file's schema: every table and key with its unit, the plausible ranges, and the reading of a
table's raw values into checked numbers (types, signs, units), each refusal one line naming the file, the
table and key, the value in its unit and the fix. Plain Python."""

import difflib
import math

from pmsmjax.spec.datasheet import DATASHEET_UNITS
from pmsmjax.spec.mechanics import FILTER_UNITS, MECHANICS_UNITS
from pmsmjax.spec.validation import ParameterError, plain

MOTOR_FIELDS = ("R", "L_d", "L_q", "psi_f", "pole_pairs", "J", "B")
MULTIPHASE_FIELDS = ("n_phases", "L_ls", "psi_f3")
MOTOR_UNITS = {"R": "ohm", "L_d": "H", "L_q": "H", "psi_f": "Wb", "pole_pairs": "", "J": "kg m^2"}
MOTOR_UNITS.update(B="N m s/rad", L_ls="H", psi_f3="Wb", n_phases="")
#: ``[motor]``'s temperature keys: the temperature its ``R`` and ``psi_f`` hold at and their coefficients.
MOTOR_TEMPERATURE_UNITS = {
    "reference_temperature_c": "degC",
    "r_temp_coeff_per_k": "1/K",
    "psi_f_temp_coeff_per_k": "1/K",
}

#: Every table and its keys with their units (``"int"``: a whole number; ``"str"``: text; ``"range"``: a
#: [low, high] pair).
TABLES = {
    "motor": {
        **MOTOR_UNITS,
        **MOTOR_TEMPERATURE_UNITS,
        "trust_units": "bool",
        "flux_map": "str",
        "flux_map_format": "str",
        **DATASHEET_UNITS,
    },  # fmt: skip
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
    "sensor": {
        "kind": "str",
        "lines": "int",
        "delay_s": "s",
        "encoder_offset_rad": "rad",
        "current_offset_a": "A list",
        "current_gain": "list",
        "current_lsb_a": "A",
    },  # fmt: skip
    "tolerances": {
        **{k: "" for k in ("R", "L_d", "L_q", "psi_f", "J", "B", "L_ls", "u_dc_v")},
        "current_offset_a": "A",
        "current_gain": "",
        "load_inertia": "",
        "shaft_stiffness_nm_per_rad": "",
    },  # fmt: skip
    "control": {
        "current_bandwidth_rad_s": "rad/s",
        "speed_bandwidth_rad_s": "rad/s",
        "startup_current_a": "A",
        "startup_acceleration_rad_s2": "rad/s^2",
        "handover_speed_rad_s": "rad/s",
        "blend_speed_rad_s": "rad/s",
        **FILTER_UNITS,
    },  # fmt: skip
    "scenario": {"speed_rpm": "r/min", "load_nm": "N m", "load_time_s": "s", "duration_s": "s"},
    "tuning": {"speed_rpm": "range", "load_nm": "range", "duration_s": "range"},
    "thermal": {"r_th_k_per_w": "K/W", "c_th_j_per_k": "J/K", "ambient_c": "degC", "initial_c": "degC"},
    "operating": {"winding_temperature_c": "range", "u_dc_v": "range", "ambient_c": "range"},
    "mechanics": MECHANICS_UNITS,
    "harmonics": {"flux": "rows [order, Wb, rad]", "cogging": "rows [order, N m, rad]"},
}
SENSOR_KINDS = ("exact", "encoder")
#: The ``[sensor]`` keys of an encoder, and of the phase-current sensors (any kind).
ENCODER_KEYS = ("lines", "delay_s", "encoder_offset_rad")
CURRENT_SENSOR_KEYS = ("current_offset_a", "current_gain", "current_lsb_a")
#: A current-sensor gain outside this range is refused (a gain is a factor near 1: 1.018 reads 1.8 % high;
#: 18 or 1.8 is a percentage typed as a factor).
CURRENT_GAIN_RANGE = (0.5, 1.5)
#: A current-sensor offset or its tolerance beyond this share of the maximum current is refused (offsets are
#: tens of mA, a few per mille of full scale: more is a unit slip, mA for A).
MAX_CURRENT_OFFSET_SHARE = 0.1
#: An ADC LSB beyond this share of the maximum current is refused (coarser than a 5-bit converter).
MAX_CURRENT_LSB_SHARE = 0.05
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
#: A run longer than this many control periods is refused (1000 s at 10 kHz: its trace alone would fill
#: gigabytes; the scan's period counter is a 32-bit integer).
MAX_RUN_PERIODS = 10**7
#: An encoder latency beyond this many control periods is refused (a unit slip: us for s).
MAX_SENSOR_DELAY_PERIODS = 10


#: No value of a drive file is this large in SI units (the largest motors' inertia is some 1e3 kg m^2): a
#: larger one is a typing slip, and beyond float32's range it would become inf inside the simulation.
MAX_MAGNITUDE = 1e12


def _one_line(text) -> str:
    return " ".join(str(text).split())


def got(value) -> str:
    """How a refusal shows a value that is not a number: a quoted number is named as a string."""
    if isinstance(value, str):
        try:
            float(value)
        except ValueError:
            return f"got the text {value!r}"
        return f"got {value!r}, a string: write the number without quotes ({value.strip()})"
    if isinstance(value, list) and any(isinstance(x, str) for x in value):
        return f"got {value!r}, which holds strings: write the numbers without quotes"
    return f"got {value!r}"


def too_large(name: str, value: float, unit: str = "") -> None:
    """Refuse a value beyond `MAX_MAGNITUDE` naming `name`."""
    if abs(value) > MAX_MAGNITUDE:
        raise ParameterError(
            f"{name} = {plain(value)}{' ' + unit if unit else ''} is beyond any physical value (at most "
            f"{plain(MAX_MAGNITUDE)} in SI units): check the number and its unit."
        )


def split_tables(data: dict, where: str) -> dict:
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


def check_keys(table: str, values: dict, where: str) -> None:
    """Refuse keys the table does not have, with the likely meant ones."""
    unknown = sorted(set(values) - set(TABLES[table]))
    if unknown:
        raise ParameterError(
            f"{where}: unknown keys {unknown} in [{table}]{_hints(unknown, TABLES[table])}; allowed: "
            f"{', '.join(TABLES[table])}."
        )


def is_number(v) -> bool:
    """Whether ``v`` is an int or a float (not a bool)."""
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def positive_number(value, key: str, name: str, unit: str = "") -> float:
    """``value`` as a float when it is finite and above 0, else a one-line refusal naming ``name``."""
    unit = f" {unit}" if unit else ""
    if not is_number(value):
        raise ParameterError(f"{name} must be a number{(' of' + unit) if unit else ''}, {got(value)}.")
    if not math.isfinite(value) or value <= 0:
        raise ParameterError(f"{name} = {plain(value)}{unit} must be a finite number above 0.")
    return float(value)


def numbers(values: dict, table: str, where: str, positive=(), signed=False, zero_ok=False) -> dict:
    """The table's values as floats, each finite and > 0 (>= 0 with `zero_ok` or for a dead time; any
    finite value with `signed`, except the keys of `positive`)."""
    out = {}
    for key, v in values.items():
        unit = TABLES[table][key]
        name = f"{where}: [{table}] {key}"
        if not is_number(v):
            raise ParameterError(f"{name} must be a number ({unit or 'relative'}), {got(v)}.")
        v = float(v)
        low_ok = (zero_ok or key in ("dead_time_s", "device_drop_v")) and v == 0.0
        if not math.isfinite(v) or ((not signed or key in positive) and v <= 0 and not low_ok):
            need = "a finite number" if signed and key not in positive else "a finite number above 0"
            raise ParameterError(f"{name} = {plain(v)} {unit}: give {need}.")
        too_large(name, v, unit)
        out[key] = v
    return out


def ranges(values: dict, where: str) -> dict:
    """The ``[tuning]`` table's ``[low, high]`` pairs, checked (``0 <= low <= high``, durations > 0)."""
    out = {}
    for key, v in values.items():
        name = f"{where}: [tuning] {key}"
        if not (isinstance(v, list) and len(v) == 2 and all(is_number(x) and math.isfinite(x) for x in v)):
            raise ParameterError(f"{name} must be [low, high], two finite numbers, {got(v)}.")
        low, high = (float(x) for x in v)
        if not 0 <= low <= high or (key == "duration_s" and low <= 0):
            raise ParameterError(
                f"{name} = [{plain(low)}, {plain(high)}]: give 0 <= low <= high (durations > 0)."
            )
        out[key] = [low, high]
    return out


#: The linear-model values a flux map stands in for.
FLUX_MAP_DERIVES = ("L_d", "L_q", "psi_f")


def flux_map_name(values: dict, where: str) -> str:
    """The ``[motor] flux_map`` file name, checked (a non-empty name, a three-phase motor)."""
    name = values["flux_map"]
    if not isinstance(name, str) or not name:
        raise ParameterError(f'{where}: [motor] flux_map must be a file name (e.g. "map.csv"), got {name!r}.')
    if values.get("n_phases", 3) != 3:
        raise ParameterError(
            f"{where}: [motor] flux_map is for a three-phase motor: drop n_phases or the map."
        )
    return name


def read_motor(values: dict, where: str, n_phases: int | None) -> dict:
    """The ``[motor]`` table checked for the machine ``n_phases`` (None: any): the fields it needs, their
    types and signs; SI floats, ``pole_pairs`` an int, ``n_phases`` only for a multi-phase motor."""
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
                raise ParameterError(f"{where}: [motor] pole_pairs must be a whole number >= 1, {got(v)}.")
            motor[key] = v
            continue
        if not is_number(v) or not math.isfinite(v):
            raise ParameterError(
                f"{where}: [motor] {key} must be a finite number ({MOTOR_UNITS[key]}), {got(v)}."
            )
        too_large(f"{where}: [motor] {key}", v, MOTOR_UNITS[key])
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


def read_sensor(values: dict, where: str) -> dict:
    """The ``[sensor]`` table checked: ``kind``, an encoder's ``lines``, ``delay_s`` and
    ``encoder_offset_rad``, and the phase-current sensors' ``current_offset_a``, ``current_gain`` (lists, one
    value per sensed phase a, b (, c), as tuples) and ``current_lsb_a``. Limits that need the drive's
    current rating are checked by [`check_current_sensors`][pmsmjax.spec.schema.check_current_sensors]."""
    kind = values.get("kind", "exact")
    if kind not in SENSOR_KINDS:
        raise ParameterError(f"{where}: [sensor] kind = {kind!r}: give one of {', '.join(SENSOR_KINDS)}.")
    sensor = {"kind": kind}
    if kind == "encoder":
        lines = values.get("lines")
        if not isinstance(lines, int) or isinstance(lines, bool) or lines < 1:
            raise ParameterError(
                f"{where}: [sensor] lines must be the encoder's lines per revolution, a whole number >= 1 "
                f"(e.g. 2500), got {lines!r}."
            )
        sensor["lines"] = lines
        delay = values.get("delay_s", 0.0)
        if not is_number(delay) or not math.isfinite(delay) or delay < 0:
            raise ParameterError(f"{where}: [sensor] delay_s must be a number >= 0 (s), {got(delay)}.")
        sensor["delay_s"] = float(delay)
        if "encoder_offset_rad" in values:
            sensor["encoder_offset_rad"] = _encoder_offset(values["encoder_offset_rad"], where)
    else:
        extra = sorted(k for k in ENCODER_KEYS if k in values)
        if extra:
            raise ParameterError(f'{where}: [sensor] {", ".join(extra)} apply to kind = "encoder" only.')
    sensor.update(_current_sensors(values, where))
    return sensor


def _encoder_offset(value, where: str) -> float:
    name = f"{where}: [sensor] encoder_offset_rad"
    if not is_number(value) or not math.isfinite(value):
        raise ParameterError(f"{name} must be a number (electrical rad), {got(value)}.")
    if abs(value) > 2.0 * math.pi:
        raise ParameterError(
            f"{name} = {plain(value)} is beyond 2 pi: it looks like degrees: write "
            f"{plain(round(math.radians(value), 6))} (electrical rad)."
        )
    return float(value)


def _current_sensors(values: dict, where: str) -> dict:
    """``current_offset_a``, ``current_gain`` (tuples of one length, 2 or 3) and ``current_lsb_a``; an LSB
    alone quantises three exact sensors."""
    given = {k: values[k] for k in CURRENT_SENSOR_KEYS if k in values}
    if not given:
        return {}
    lists = {}
    for key in ("current_offset_a", "current_gain"):
        if key not in given:
            continue
        v = given[key]
        unit = " (A)" if key == "current_offset_a" else ""
        if not isinstance(v, list) or not all(is_number(x) and math.isfinite(x) for x in v):
            raise ParameterError(
                f"{where}: [sensor] {key} must be a list of finite numbers{unit}, one per sensed phase "
                f"a, b (, c), e.g. {'[0.11, -0.07]' if unit else '[1.0, 1.018]'}; {got(v)}."
            )
        if len(v) not in (2, 3):
            raise ParameterError(
                f"{where}: [sensor] {key} has {len(v)} values: give 2 (sensors on phases a and b, c "
                "reconstructed as -a - b) or 3 (one per phase)."
            )
        lists[key] = tuple(float(x) for x in v)
    if len({len(v) for v in lists.values()}) > 1:
        o, g = lists["current_offset_a"], lists["current_gain"]
        raise ParameterError(
            f"{where}: [sensor] current_offset_a has {len(o)} values and current_gain {len(g)}: give one "
            "value per sensed phase in both lists (the length is the number of sensors)."
        )
    n = len(next(iter(lists.values()))) if lists else 3
    lists.setdefault("current_offset_a", (0.0,) * n)
    lists.setdefault("current_gain", (1.0,) * n)
    low, high = CURRENT_GAIN_RANGE
    for k, g in enumerate(lists["current_gain"]):
        if not low <= g <= high:
            raise ParameterError(
                f"{where}: [sensor] current_gain[{k}] = {plain(g)} is not a sensor gain (a factor near 1, "
                f"{plain(low)}-{plain(high)}): write 1 + the error, e.g. {plain(1 + g / 100)} for "
                f"{plain(g)} % or {plain(1 + g / 1000)} for {plain(g / 10)} %."
            )
    if "current_lsb_a" in given:
        lists["current_lsb_a"] = positive_number(
            given["current_lsb_a"], "current_lsb_a", f"{where}: [sensor] current_lsb_a", "A"
        )
    return lists


def check_current_sensors(sensor: dict, tolerances: dict, max_current_a: float, where: str) -> None:
    """Refuse current-sensor offsets, offset tolerances and LSBs implausible for a drive whose maximum
    current is ``max_current_a`` (A), and current-sensor tolerances without the sensors they spread."""
    limit = MAX_CURRENT_OFFSET_SHARE * max_current_a
    offsets = [
        (f"[sensor] current_offset_a[{k}]", o) for k, o in enumerate(sensor.get("current_offset_a", ()))
    ]
    if "current_offset_a" in tolerances:
        offsets.append(("[tolerances] current_offset_a", tolerances["current_offset_a"]))
    for name, o in offsets:
        if abs(o) > limit:
            raise ParameterError(
                f"{where}: {name} = {plain(o)} A is {100 * abs(o) / max_current_a:.3g} % of the "
                f"{plain(max_current_a)} A maximum current: sensor offsets are tens of mA (at most "
                f"{plain(100 * MAX_CURRENT_OFFSET_SHARE)} %, {plain(limit)} A); in mA? write "
                f"{plain(o / 1000)} (A)."
            )
    lsb = sensor.get("current_lsb_a")
    if lsb is not None and lsb > MAX_CURRENT_LSB_SHARE * max_current_a:
        raise ParameterError(
            f"{where}: [sensor] current_lsb_a = {plain(lsb)} A is {100 * lsb / max_current_a:.3g} % of the "
            f"{plain(max_current_a)} A maximum current, coarser than a 5-bit converter: give one ADC step in "
            f"A (a 12-bit ADC over +-{plain(max_current_a)} A: {plain(2 * max_current_a / 4096)})."
        )
    spread = sorted(k for k in ("current_offset_a", "current_gain") if k in tolerances)
    if spread and "current_offset_a" not in sensor:
        raise ParameterError(
            f"{where}: [tolerances] {', '.join(spread)} spread the current sensors, which [sensor] does not "
            "give: add them, e.g. current_offset_a = [0.0, 0.0] for two sensors on phases a and b."
        )


def read_thermal(motor: dict, thermal: dict, where: str) -> tuple[dict, dict]:
    """``[motor]``'s temperature keys and the ``[thermal]`` table as floats, each a finite number (the
    thermal resistance and capacity above 0); their plausibility is
    [`pmsmjax.spec.plausibility.check_thermal_units`][pmsmjax.spec.plausibility.check_thermal_units]'s."""
    temperature = {}
    for key, unit in MOTOR_TEMPERATURE_UNITS.items():
        if key in motor:
            v = motor[key]
            if not is_number(v) or not math.isfinite(v):
                raise ParameterError(f"{where}: [motor] {key} must be a finite number ({unit}), {got(v)}.")
            temperature[key] = float(v)
    values = numbers(thermal, "thermal", where, positive=("r_th_k_per_w", "c_th_j_per_k"), signed=True)
    return temperature, values


def read_operating(values: dict, where: str) -> dict:
    """The ``[operating]`` table's ``[low, high]`` pairs, checked (finite, ``low <= high``; the DC link
    above 0)."""
    out = {}
    for key, v in values.items():
        name = f"{where}: [operating] {key}"
        unit = {"u_dc_v": "V"}.get(key, "degC")
        if not (isinstance(v, list) and len(v) == 2 and all(is_number(x) and math.isfinite(x) for x in v)):
            raise ParameterError(f"{name} must be [low, high], two finite numbers in {unit}, {got(v)}.")
        low, high = (float(x) for x in v)
        if not low <= high or (key == "u_dc_v" and low <= 0):
            need = "0 < low <= high" if key == "u_dc_v" else "low <= high"
            raise ParameterError(f"{name} = [{plain(low)}, {plain(high)}] {unit}: give {need}.")
        out[key] = [low, high]
    return out
