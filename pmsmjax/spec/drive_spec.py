"""The drive spec: a drive file's tables checked and completed, for every command, before JAX starts (the
file itself is read by [`pmsmjax.io.drive_files`][pmsmjax.io.drive_files]).

Layout (SI units; every table but ``[motor]`` optional)::

    [motor]        R, L_d, L_q, psi_f, pole_pairs, J, B (ohm, H, H, Wb, -, kg m^2, N m s/rad);
                   n_phases = 6 or 5 with L_ls (H) and, five-phase, psi_f3 (Wb); trust_units = true;
                   flux_map = "map.csv" (three-phase: a measured flux map, path relative to the drive
                   file, read by pmsmjax.io.flux_map_files; L_d, L_q, psi_f then optional) and
                   flux_map_format = "grid" | "points" | "syre" | "inductance" | "motulator"
                   (pmsmjax.io.flux_map_formats; default: by the file's extension and content);
                   datasheet values instead of R, L_d, L_q, psi_f: r_ll_ohm, l_ll_h,
                   ke_v_peak_per_krpm_ll or ke_v_rms_per_krpm_ll, kt_nm_per_a_rms or kt_nm_per_a_peak,
                   kv_rpm_per_v (pmsmjax.spec.datasheet, each convention there)
    [ratings]      rated_speed_rpm, rated_torque_nm or rated_current_a (A peak), max_current_a (A peak)
    [inverter]     u_dc_v, switching_frequency_hz, control_frequency_hz (default: the switching
                   frequency), dead_time_s, device_drop_v (a switch's or diode's on-state voltage, V),
                   dead_time_compensation = true | false (default true: the controller adds the dead
                   time's and drop's predicted error back, as drive firmware does)
    [sensor]       kind = "exact" | "encoder", lines (per mechanical revolution), delay_s,
                   encoder_offset_rad (electrical rad); the phase-current sensors (any kind):
                   current_offset_a = [0.11, -0.07] (A, one per sensed phase a, b (, c): the length is the
                   number of sensors), current_gain = [1.0, 1.018], current_lsb_a (A, one ADC step)
    [tolerances]   relative half-widths of the parameters' spread: R = 0.05 (+-5 %), L_d, L_q, psi_f, J, B,
                   u_dc_v, current_gain; current_offset_a in A (0.05: +-50 mA on each sensor) (Monte Carlo
                   draws, robust tuning)
    [control]      current_bandwidth_rad_s, speed_bandwidth_rad_s, startup_current_a,
                   startup_acceleration_rad_s2, handover_speed_rad_s, blend_speed_rad_s
    [scenario]     speed_rpm, load_nm, load_time_s, duration_s (the demo, compare and Monte Carlo run)
    [tuning]       speed_rpm = [low, high], load_nm = [low, high], duration_s = [low, high]
    [thermal]      r_th_k_per_w, c_th_j_per_k (the winding's thermal resistance to ambient and heat
                   capacity), ambient_c (default 40 degC), initial_c (default the ambient): a warm motor,
                   R(T) and psi_f(T) from [motor] reference_temperature_c (default 20),
                   r_temp_coeff_per_k (default copper's 0.00393) and psi_f_temp_coeff_per_k (default
                   sintered NdFeB's -0.0011), three-phase motors
    [operating]    what varies in use, [low, high]: winding_temperature_c (a run's initial winding
                   temperature; needs [thermal]), u_dc_v, ambient_c (needs [thermal]) (Monte Carlo draws,
                   robust tuning)
    [mechanics]    a compliant shaft: load_inertia (kg m^2; [motor] J is then the motor's own),
                   shaft_stiffness_nm_per_rad, shaft_damping_nm_s_per_rad (default 0); [tolerances]
                   load_inertia and shaft_stiffness_nm_per_rad spread them; [control] speed_filter_hz,
                   notch_hz, notch_width_hz, notch_depth_db: the speed loop's filters
                   (pmsmjax.spec.mechanics)
    [harmonics]    flux = [[5, 0.0019, 0.4], ...] (magnet flux harmonics: order per electrical revolution,
                   Wb, rad), cogging = [[6, 0.045, 0.3], ...] (cogging torque: order, N m, rad), three-phase
                   motors (pmsmjax.spec.harmonics)

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
([`pmsmjax.spec.design_rules`][pmsmjax.spec.design_rules] has the rules and their sources) and each derived
value is listed, with how, in [`DriveSpec.derived`][pmsmjax.spec.drive_spec.DriveSpec] (``summary.json``'s
``drive_file.derived``).

Checked, each a one-line [`ParameterError`][pmsmjax.spec.validation.ParameterError] naming the file, the table
and key, the value in its unit and the fix: TOML syntax, unknown tables and keys (with the likely meant one),
types, units (an inductance in mH, [`pmsmjax.spec.plausibility`][pmsmjax.spec.plausibility]; a DC link in kV,
a switching frequency in kHz, a dead time in us), a dead time that eats the switching period, a maximum
current below the rated current, a rated torque the maximum current cannot give, and a rated point the
inverter cannot reach (even with field weakening).
"""

import dataclasses
from collections.abc import Mapping

import numpy as np

from pmsmjax.spec import datasheet, schema
from pmsmjax.spec import derivations as derive
from pmsmjax.spec import design_rules as rules
from pmsmjax.spec.harmonics import read_harmonics
from pmsmjax.spec.mechanics import complete_filters, read_mechanics, rigid_equivalent
from pmsmjax.spec.plausibility import check_flux_map_units, check_motor_units, check_thermal_units
from pmsmjax.spec.schema import (
    DC_LINK_RANGE_V,
    MAX_SENSOR_DELAY_PERIODS,
    MOTOR_FIELDS,
    TABLES,
    check_keys,
    flux_map_name,
    split_tables,
)
from pmsmjax.spec.tables import (
    ControlTable,
    HarmonicsTable,
    InverterTable,
    MechanicsTable,
    MotorTable,
    OperatingTable,
    RatingsTable,
    ScenarioTable,
    SensorTable,
    ThermalTable,
    ToleranceTable,
    TuningTable,
)
from pmsmjax.spec.validation import ParameterError, plain

__all__ = ["DriveSpec", "complete", "split_tables", "check_keys", "flux_map_name", "TABLES", "MOTOR_FIELDS"]


@dataclasses.dataclass(frozen=True)
class DriveSpec:
    """A checked drive: the file's tables ([`pmsmjax.spec.tables`][pmsmjax.spec.tables], typed and frozen)
    with every absent value derived.

    - `source`: the preset name or file path;
    - `motor`: SI values (``n_phases`` present only for a multi-phase motor);
    - `ratings`: ``rated_speed_rpm, rated_torque_nm, rated_current_a, max_current_a``;
    - `inverter`: ``u_dc_v, switching_frequency_hz, control_frequency_hz, dead_time_s, device_drop_v``
      and ``dead_time_compensation`` (bool);
    - `sensor`: ``kind`` and, for an encoder, ``lines``, ``delay_s``, ``encoder_offset_rad``; the current
      sensors' ``current_offset_a``, ``current_gain`` (tuples) and ``current_lsb_a`` where the file gives
      them;
    - `tolerances`: relative half-widths (``current_offset_a`` in A; only those the file gives);
    - `control`, `scenario`, `tuning`: as the file's tables, complete;
    - `derived`: ``{"table.key": how}`` for every value the file left out;
    - `notes`: what a user should know about the drive (a rated point that needs field weakening);
    - `flux_map`: the ``[motor] flux_map`` grid as read once
      ([`FluxMapGrid`][pmsmjax.machines.flux_map.FluxMapGrid]), None without one.
    - `thermal`: the winding's thermal network (``[thermal]``, complete), empty without one;
    - `operating`: the ranges of ``[operating]`` the file gives;
    - `mechanics`: the compliant shaft of ``[mechanics]`` (complete), empty for a rigid shaft;
    - `harmonics`: the magnet flux harmonics and cogging torque (``[harmonics]``), empty without them.
    """

    source: str
    motor: MotorTable
    ratings: RatingsTable
    inverter: InverterTable
    sensor: SensorTable
    tolerances: ToleranceTable
    control: ControlTable
    scenario: ScenarioTable
    tuning: TuningTable
    derived: dict
    notes: tuple = ()
    flux_map: object = dataclasses.field(default=None, compare=False, repr=False)
    #: ``{table: keys}`` in the order the file gave them and the derivations added them: the order
    #: summary.json lists them in (a table's own iteration is its field order).
    key_order: dict | None = dataclasses.field(default=None, compare=False, repr=False)
    thermal: ThermalTable = dataclasses.field(default_factory=ThermalTable)
    operating: OperatingTable = dataclasses.field(default_factory=OperatingTable)
    mechanics: MechanicsTable = dataclasses.field(default_factory=MechanicsTable)
    harmonics: HarmonicsTable = dataclasses.field(default_factory=HarmonicsTable)

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
        order = self.key_order or {}

        def table(name):
            values = getattr(self, name)
            return {key: values[key] for key in order.get(name, values)}

        return {
            "source": self.source,
            **{t: table(t) for t in ("motor", "ratings", "inverter", "sensor", "tolerances")},
            **{t: table(t) for t in ("control", "scenario", "tuning")},
            **{t: table(t) for t in ("thermal", "operating", "mechanics", "harmonics") if getattr(self, t)},
            "derived": dict(self.derived),
            "notes": list(self.notes),
        }


def complete(
    tables: dict,
    *,
    where: str,
    source: str,
    n_phases: int | None = None,
    check_units: bool = True,
    overrides: Mapping[str, float] | None = None,
    flags: Mapping[str, str] | None = None,
    flux_map=None,
    flux_map_path: str | None = None,
    flux_map_how: str = "",
) -> DriveSpec:
    """Check and complete a drive file's tables (module docstring).

    Args:
        tables: ``{table: {key: value}}`` as [`split_tables`][pmsmjax.spec.schema.split_tables] gives them
            (every table, empty when the file leaves it out), keys checked by
            [`check_keys`][pmsmjax.spec.schema.check_keys].
        where: how messages name the file (``"drive file motor.toml"``).
        source: the preset name or file path the spec reports.
        n_phases: the machine the command runs (a file for another is refused); None: any.
        check_units: refuse values implausible in SI units (unless the file trusts its units).
        overrides: ``u_dc_v`` (V) and ``max_current_a`` (A) from flags, over the file's.
        flags: how messages name the overrides (``{"u_dc_v": "--u-dc"}``).
        flux_map: the ``[motor] flux_map`` grid ([`FluxMapGrid`][pmsmjax.machines.flux_map.FluxMapGrid]) as
            read.
        flux_map_path: its absolute path (what ``motor["flux_map"]`` reports).
        flux_map_how: how the map file was converted or filled (``derived["motor.flux_map"]``), empty for
            a complete grid in pmsmjax's layout.

    Returns:
        The checked, completed drive.
    """
    tables = {table: dict(values) for table, values in tables.items()}  # completed in place below
    flux_map_derived = datasheet.convert(tables["motor"], where)  # r_ll_ohm, ke, kt, kv: to R, L, psi_f
    if flux_map_how:
        flux_map_derived["motor.flux_map"] = flux_map_how
    if flux_map is not None:
        if check_units and tables["motor"].get("trust_units", False) is not True:
            peak = max(
                float(abs(np.asarray(flux_map.psi_d)).max()), float(abs(np.asarray(flux_map.psi_q)).max())
            )
            check_flux_map_units(peak, f"{where} [motor] flux_map {flux_map_path}")
        flux_map_derived |= derive.flux_map_motor(tables["motor"], tables["ratings"], flux_map, flux_map_path)
    motor = schema.read_motor(tables["motor"], where, n_phases)
    trust = tables["motor"].get("trust_units", False)
    ratings = schema.numbers(tables["ratings"], "ratings", where)
    compensation = tables["inverter"].pop("dead_time_compensation", None)
    if compensation is not None and not isinstance(compensation, bool):
        raise ParameterError(
            f"{where}: [inverter] dead_time_compensation must be true or false, got {compensation!r}."
        )
    inverter = schema.numbers(tables["inverter"], "inverter", where)
    control = schema.numbers(tables["control"], "control", where)
    scenario = schema.numbers(tables["scenario"], "scenario", where, positive=("duration_s",), signed=True)
    tolerances = schema.numbers(tables["tolerances"], "tolerances", where, zero_ok=True)
    if scenario.get("load_time_s", 0.0) < 0.0:
        raise ParameterError(
            f"{where}: [scenario] load_time_s = {plain(scenario['load_time_s'])} s: give a time >= 0 (s "
            "after the start of the run)."
        )
    tuning = schema.ranges(tables["tuning"], where)
    temperature, thermal = schema.read_thermal(tables["motor"], tables["thermal"], where)
    operating = schema.read_operating(tables["operating"], where)
    check_thermal_units(temperature, thermal, operating, where, trust is True or not check_units)
    sensor = schema.read_sensor(tables["sensor"], where)
    for key, value in (overrides or {}).items():
        table = "inverter" if key == "u_dc_v" else "ratings"
        schema.positive_number(value, key, (flags or {}).get(key, f"[{table}] {key}"))
        (inverter if table == "inverter" else ratings)[key] = float(value)
    name_of = derive.namer(where, flags or {}, overrides or {})

    derived = dict(flux_map_derived)
    derive.complete_inverter(inverter, derived, name_of)
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
    derive.complete_ratings(motor, ratings, inverter, derived, name_of)
    notes = derive.check_rated_point(motor, ratings, inverter, name_of)
    shaft = read_mechanics(tables["mechanics"], motor, where)
    derive.complete_control(rigid_equivalent(motor, shaft), ratings, control, Ts, derived, where)
    complete_filters(control, Ts, derived, where)
    mechanics = {} if not shaft else {
        "load_inertia": shaft["load_inertia"], "shaft_stiffness_nm_per_rad": shaft["shaft_stiffness"],
        "shaft_damping_nm_s_per_rad": shaft["shaft_damping"],
    }  # fmt: skip
    spread = sorted(k for k in ("load_inertia", "shaft_stiffness_nm_per_rad") if k in tolerances)
    if spread and not shaft:
        raise ParameterError(
            f"{where}: [tolerances] {', '.join(spread)} spread a compliant shaft, which the file does not "
            "give: add [mechanics] (load_inertia, shaft_stiffness_nm_per_rad) or drop them."
        )
    schema.check_current_sensors(sensor, tolerances, ratings["max_current_a"], where)
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
                derived[f"scenario.{key}"] = derive.SCENARIO_HOW[key]
    if not scenario["load_time_s"] < scenario["duration_s"]:
        raise ParameterError(
            f"{where}: [scenario] load_time_s = {plain(scenario['load_time_s'])} s is not inside the run "
            f"(duration_s = {plain(scenario['duration_s'])} s): give a load time below the duration."
        )
    durations = {"[scenario] duration_s": scenario["duration_s"]}
    if "duration_s" in tuning:
        durations["[tuning] duration_s"] = tuning["duration_s"][1]
    for name, duration in durations.items():
        if duration / Ts > schema.MAX_RUN_PERIODS:
            longest = plain(schema.MAX_RUN_PERIODS * Ts)
            raise ParameterError(
                f"{where}: {name} = {plain(duration)} s is {duration / Ts:.3g} control periods, more than "
                f"the {schema.MAX_RUN_PERIODS:.0e} a run may have ({longest} s at {plain(1.0 / Ts)} Hz): "
                f"give a duration in s, at most {longest}."
            )
    if not tuning.keys() >= TABLES["tuning"].keys():
        rule = rules.tuning_ranges(
            motor, ratings["rated_speed_rpm"], ratings["rated_torque_nm"], ratings["max_current_a"],
            inverter["u_dc_v"], control["speed_bandwidth_rad_s"],
        )  # fmt: skip
        for key, value in rule.items():
            if key not in tuning:
                tuning[key] = value
                derived[f"tuning.{key}"] = derive.TUNING_HOW[key]
    complete_thermal(motor, temperature, thermal, operating, derived, where)
    harmonics = read_harmonics(tables["harmonics"], motor, ratings, where, trust is True or not check_units)
    for key, value in tolerances.items():
        if key != "current_offset_a" and not value < 1.0:
            raise ParameterError(
                f"{where}: [tolerances] {key} = {plain(value)} is a relative half-width and must be below 1 "
                f"(0.05 for +-5 %); a spread of {plain(100 * value)} % would reach zero or below."
            )
    tables = dict(
        motor=motor, ratings=ratings, inverter=inverter, sensor=sensor, tolerances=tolerances,
        control=control, scenario=scenario, tuning=tuning, thermal=thermal, operating=operating,
        mechanics=mechanics,
        harmonics=harmonics,
    )  # fmt: skip
    return DriveSpec(
        source, MotorTable.of(motor), RatingsTable.of(ratings), InverterTable.of(inverter),
        SensorTable.of(sensor), ToleranceTable.of(tolerances), ControlTable.of(control),
        ScenarioTable.of(scenario), TuningTable.of(tuning), derived, tuple(notes), flux_map,
        {name: tuple(values) for name, values in tables.items()}, ThermalTable.of(thermal),
        OperatingTable.of(operating), MechanicsTable.of(mechanics), HarmonicsTable.of(harmonics),
    )  # fmt: skip


#: Defaults of a drive file with ``[thermal]``: ``{key: (value, how)}``.
THERMAL_DEFAULTS = {
    "motor.reference_temperature_c": (20.0, "20 degC, the temperature data sheets state R at"),
    "motor.r_temp_coeff_per_k": (0.00393, "copper's 0.00393 /K at 20 degC (IEC 60028)"),
    "motor.psi_f_temp_coeff_per_k": (
        -0.0011,
        "sintered NdFeB's -0.11 %/K (magnet data sheets: -0.10 to -0.12 %/K)",
    ),
    "thermal.ambient_c": (40.0, "40 degC, the reference coolant temperature of IEC 60034-1"),
}


def complete_thermal(motor, temperature, thermal, operating, derived, where) -> None:
    """Put ``[motor]``'s temperature keys into ``motor`` and complete ``[thermal]`` (defaults noted in
    ``derived``); refuse a ``[thermal]`` without its network's values, on a multi-phase motor, and an
    ``[operating]`` temperature range without ``[thermal]`` or a DC-link band outside a drive's."""
    motor.update(temperature)
    if not thermal:
        needs = [k for k in ("winding_temperature_c", "ambient_c") if k in operating]
        if needs:
            raise ParameterError(
                f"{where}: [operating] {', '.join(needs)} vary the winding's temperature, which needs a "
                "thermal model: add [thermal] with r_th_k_per_w (K/W) and c_th_j_per_k (J/K)."
            )
    else:
        if motor.get("n_phases", 3) != 3:
            raise ParameterError(
                f"{where}: [thermal] heats a three-phase motor (copper loss 1.5 R |i_dq|^2); this motor has "
                f"{motor['n_phases']} phases: drop [thermal]."
            )
        missing = [k for k in ("r_th_k_per_w", "c_th_j_per_k") if k not in thermal]
        if missing:
            raise ParameterError(
                f"{where}: [thermal] lacks {', '.join(missing)}: give the winding's thermal resistance to "
                "ambient r_th_k_per_w (K/W: the steady winding rise over the copper loss, e.g. 60 K / 120 W "
                "= 0.5) and heat capacity c_th_j_per_k (J/K: the heating time constant over r_th)."
            )
        for name, (value, how) in THERMAL_DEFAULTS.items():
            table, key = name.split(".")
            values = motor if table == "motor" else thermal
            if key not in values:
                values[key] = value
                derived[name] = how
        if "initial_c" not in thermal:
            thermal["initial_c"] = thermal["ambient_c"]
            derived["thermal.initial_c"] = "the ambient: a cold start"
    band = operating.get("u_dc_v")
    if band is not None and not (DC_LINK_RANGE_V[0] <= band[0] and band[1] <= DC_LINK_RANGE_V[1]):
        raise ParameterError(
            f"{where}: [operating] u_dc_v = [{plain(band[0])}, {plain(band[1])}] V is outside the "
            f"{plain(DC_LINK_RANGE_V[0])}-{plain(DC_LINK_RANGE_V[1])} V of drive DC links: give it in V."
        )
