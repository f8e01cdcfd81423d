"""The identified motor as a drive file (``DIR/motor.toml`` of ``pmsmjax identify``), readable by
[`pmsmjax.io.drive_files.drive_spec`][pmsmjax.io.drive_files.drive_spec] and so by every command
(``--motor DIR/motor.toml``).

- ``[motor]``: the identified values; a parameter held fixed (``--fix``) keeps its given value; a parameter
  the log does not determine (``identifiable`` false in ``params.json``) takes the prior's value
  (``--motor PRIOR``), with a comment saying so. Without a prior such a parameter has no value to write:
  [`undetermined`][tuning.identify.motor_file.undetermined] names it and the file is not written
  (``params.json`` still is).
- ``[tolerances]``: for an identified parameter the relative half-width of its 95 % interval, the larger
  of its two sides (the interval is not symmetric: it is symmetric in ``log`` of the value); a prior's
  value keeps the prior file's tolerance, if it has one; a fixed value gets none.
- ``[ratings]``, ``[inverter]``, ``[sensor]``: copied from the prior, only the values its file states
  (values it derived came from the prior's motor and are derived again from the identified one).
- With identified sensor errors (``sensor_errors`` in ``params.json``, ``pmsmjax identify --sensor-errors``):
  ``[sensor]`` ``current_offset_a`` and ``current_gain`` (relative to sensor a, whose gain is written as 1:
  a log does not give the absolute gain) and, for an encoder (``kind = "encoder"`` in the prior; its lines
  are not in a log), ``encoder_offset_rad``; ``[tolerances]`` ``current_offset_a`` (A) and ``current_gain``
  the largest half-widths of their 95 % intervals. A value the log does not determine is not written.
- With a winding-temperature column (``temperature`` in ``params.json``): ``[motor]``
  ``reference_temperature_c``, ``r_temp_coeff_per_k`` and ``psi_f_temp_coeff_per_k`` (R and psi_f are then
  the values at the reference temperature), and ``[thermal]`` ``r_th_k_per_w``, ``c_th_j_per_k`` and
  ``ambient_c`` of the fitted network, each only when identified. ``[operating]`` (the ranges a drive runs
  over) is the user's and is carried over from the prior: the intervals go to ``[tolerances]``, never to
  ``[operating]``.
- With identified ripple (``harmonics`` in ``params.json``, ``--flux-harmonics``, ``--cogging-orders``):
  ``[harmonics]`` ``flux`` and ``cogging`` rows ``[order, amplitude, phase]`` of the orders the log
  determines ([`tuning.identify.ripple_stage.harmonics_table`][tuning.identify.ripple_stage.harmonics_table]);
  without them the prior's ``[harmonics]`` is carried over.
- With an identified shaft (``two_mass`` in ``params.json``, ``--two-mass``): ``[motor]`` ``J`` and ``B`` the
  motor's own (the two-mass fit's ``J_m``, ``B``) and ``[mechanics]`` ``load_inertia``,
  ``shaft_stiffness_nm_per_rad``, ``shaft_damping_nm_s_per_rad``, each with its tolerance; a value the log
  does not determine is not written (the shaft is written only when the inertia and the stiffness are).
"""

from pathlib import Path

from pmsmjax.io.drive_files import write_drive_file
from pmsmjax.spec.drive_spec import DriveSpec

__all__ = ["MOTOR_NAMES", "undetermined", "motor_file_tables", "prior_stated_tables", "write_motor_file"]

#: The identified parameters a drive file's ``[motor]`` holds (pole pairs are given, not identified).
MOTOR_NAMES = ("R", "L_d", "L_q", "psi_f", "J", "B")


def undetermined(summary: dict) -> list[str]:
    """The motor parameters of ``summary`` (``params.json``) that the log does not determine."""
    shaft = _shaft_values(summary)
    return [n for n in MOTOR_NAMES if summary["parameters"][n]["identifiable"] is False and n not in shaft]


def _half_width(entry: dict) -> float:
    """Relative half-width of an identified value's 95 % interval (the larger side)."""
    lo, hi = entry["ci95"]
    v = entry["value"]
    return max(v - lo, hi - v) / abs(v)


def motor_file_tables(summary: dict, pole_pairs: int, prior: DriveSpec | None = None) -> tuple[dict, dict]:
    """``(tables, comments)`` of the drive file of an identification ``summary`` (``params.json``) and
    an optional ``prior`` drive (module docstring). Raises ValueError when a parameter is undetermined
    and there is no prior (check [`undetermined`][tuning.identify.motor_file.undetermined] first)."""
    motor, tolerances, comments = {}, {}, {}
    for name in MOTOR_NAMES:
        entry = summary["parameters"][name]
        if entry["identifiable"] is False:
            if prior is None:
                raise ValueError(f"{name} is not determined by the log and there is no prior")
            motor[name] = prior.motor[name]
            comments[f"motor.{name}"] = f"not determined by the log: the prior's value ({prior.source})"
            if name in prior.tolerances:
                tolerances[name] = prior.tolerances[name]
                comments[f"tolerances.{name}"] = "the prior's tolerance"
        elif entry["fixed"]:
            motor[name] = entry["value"]
            comments[f"motor.{name}"] = "held fixed (--fix), not identified"
        else:
            motor[name] = entry["value"]
            tolerances[name] = _half_width(entry)
        if name == "psi_f":
            motor["pole_pairs"] = pole_pairs
    tables = {"motor": motor}
    if prior is not None:
        tables |= prior_stated_tables(prior)
        if prior.sensor["kind"] != "exact":
            tables["sensor"] = dict(prior.sensor)
        if "u_dc_v" in prior.tolerances:
            tolerances["u_dc_v"] = prior.tolerances["u_dc_v"]
    if summary.get("sensor_errors"):
        sensor = _sensor_table(summary["sensor_errors"], prior, tolerances, comments)
        if sensor != {"kind": "exact"}:
            tables["sensor"] = sensor
    if summary.get("temperature"):
        tables |= _temperature_tables(summary["temperature"], motor, prior, comments)
    _ripple_tables(summary, prior, tables, comments)
    shaft = _shaft_values(summary)
    if shaft:
        two = summary["two_mass"]
        for name, key in (("J", "J_m"), ("B", "B")):
            if name in shaft:
                motor[name], tolerances[name] = shaft[name], _half_width(two[key])
                comments[f"motor.{name}"] = "the two-mass fit's (the motor's own)"
        mechanics = {k: shaft[k] for k in _SHAFT_KEYS.values() if k in shaft}
        tables["mechanics"] = mechanics
        for key in ("load_inertia", "shaft_stiffness_nm_per_rad"):
            tolerances[key] = _half_width(two[{v: k for k, v in _SHAFT_KEYS.items()}[key]])
        if "shaft_damping_nm_s_per_rad" not in mechanics:
            comments["mechanics.load_inertia"] = "the damping is not determined by the log: 0 (undamped)"
    if tolerances:
        tables["tolerances"] = tolerances
    return tables, comments


def _sensor_table(errors: dict, prior: DriveSpec | None, tolerances: dict, comments: dict) -> dict:
    """The ``[sensor]`` table with the identified sensor errors (module docstring); fills `tolerances`
    and `comments`."""
    sensor = dict(prior.sensor) if prior is not None else {"kind": "exact"}
    offsets, gains = errors["current_offset_a"], errors["current_gain"]
    if all(e["identifiable"] is not False for e in offsets + gains):
        sensor["current_offset_a"] = [e["value"] for e in offsets]
        sensor["current_gain"] = [e["value"] for e in gains]
        comments["sensor.current_offset_a"] = "identified (A)"
        comments["sensor.current_gain"] = "relative to sensor a: a log does not give the absolute gain"
        tolerances["current_offset_a"] = max(e["ci95"][1] - e["value"] for e in offsets)
        tolerances["current_gain"] = max((e["ci95"][1] - e["value"]) / e["value"] for e in gains)
    enc = errors["encoder_offset_rad"]
    if enc["identifiable"]:
        if sensor["kind"] == "encoder":
            sensor["encoder_offset_rad"] = enc["value"]
            comments["sensor.encoder_offset_rad"] = "identified (electrical rad)"
        else:
            comments["sensor.kind"] = (
                f"identified encoder offset {enc['value']:.6g} electrical rad: an encoder (kind = "
                '"encoder", its lines) takes it as encoder_offset_rad'
            )
    return sensor


def _temperature_tables(report: dict, motor: dict, prior: DriveSpec | None, comments: dict) -> dict:
    """``[motor]``'s temperature keys (added to `motor`) and the ``[thermal]`` and ``[operating]`` tables of
    an identified temperature ``report`` (module docstring)."""
    coefficients = ("r_temp_coeff_per_k", "psi_f_temp_coeff_per_k")
    if all(report[n]["identifiable"] for n in coefficients):
        motor["reference_temperature_c"] = report["reference_temperature_c"]
        for name in coefficients:
            motor[name] = report[name]["value"]
            comments[f"motor.{name}"] = "identified (1/K)"
    tables = {}
    network = report.get("thermal_network", {})
    names = ("r_th_k_per_w", "c_th_j_per_k")
    if network and all(network.get(n, {}).get("identifiable") for n in names):
        thermal = {n: network[n]["value"] for n in names}
        thermal["ambient_c"] = network["ambient_c"]["value"]
        comments["thermal.r_th_k_per_w"] = (
            "identified: per ampere as sensor a reads it (scales with 1 / its gain)"
        )
        comments["thermal.ambient_c"] = "given" if network["ambient_c"].get("given") else "identified"
        tables["thermal"] = thermal
    elif prior is not None and prior.thermal:
        tables["thermal"] = dict(prior.thermal)
    if prior is not None and prior.operating:
        tables["operating"] = {k: list(v) for k, v in prior.operating.items()}
    return tables


_SHAFT_KEYS = {"J_L": "load_inertia", "K": "shaft_stiffness_nm_per_rad", "D": "shaft_damping_nm_s_per_rad"}


def _shaft_values(summary: dict) -> dict:
    """``{J, B, load_inertia, shaft_stiffness_nm_per_rad, shaft_damping_nm_s_per_rad}``: the identified
    values of ``params.json``'s ``two_mass`` (empty unless J_L and K are identified)."""
    two = summary.get("two_mass")
    if not two or not (two["J_L"]["identifiable"] and two["K"]["identifiable"]):
        return {}
    out = {v: two[k]["value"] for k, v in _SHAFT_KEYS.items() if two[k]["identifiable"]}
    out |= {n: two[k]["value"] for n, k in (("J", "J_m"), ("B", "B")) if two[k]["identifiable"]}
    return out


def _ripple_tables(summary: dict, prior: DriveSpec | None, tables: dict, comments: dict) -> None:
    """Add ``[harmonics]`` (identified, else the prior's) to `tables` (module docstring)."""
    from tuning.identify.ripple_stage import harmonics_table

    table, notes = harmonics_table(summary.get("harmonics") or {})
    if table:
        tables["harmonics"] = table
        for key in table:
            comments[f"harmonics.{key}"] = "identified: [order, amplitude, phase (rad)]" + (
                "; " + "; ".join(notes) if notes else ""
            )
    elif prior is not None and prior.harmonics:
        tables["harmonics"] = {k: [list(r) for r in v] for k, v in dict(prior.harmonics).items()}


def write_motor_file(path, summary: dict, pole_pairs: int, prior: DriveSpec | None = None) -> Path:
    """Write the drive file of ``summary`` (and ``prior``) to ``path``; returns the path."""
    tables, comments = motor_file_tables(summary, pole_pairs, prior)
    header = (
        f"Identified by pmsmjax identify from {summary['log']['source']} (tuning.identify): [motor] the\n"
        "fitted values (SI units), [tolerances] the relative half-widths of their 95 % intervals"
    )
    if prior is not None:
        header += f";\n[ratings], [inverter], [sensor] and undetermined values from the prior {prior.source}"
    if summary.get("sensor_errors"):
        header += (
            ";\n[sensor] the identified current-sensor offsets, gains relative to sensor a and encoder offset"
        )
    header += "."
    write_drive_file(path, tables, header=header, comments=comments)
    return Path(path)


def prior_stated_tables(prior) -> dict:
    """The prior drive file's ``[ratings]`` and ``[inverter]`` values it states (not those derived from
    the rest), which an identified drive file carries over: ``{table: {key: value}}``."""
    tables = {}
    for table in ("ratings", "inverter"):
        stated = {k: v for k, v in getattr(prior, table).items() if f"{table}.{k}" not in prior.derived}
        if stated:
            tables[table] = stated
    return tables
