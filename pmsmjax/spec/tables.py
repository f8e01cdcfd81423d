"""The drive file's tables as typed, frozen values: one dataclass per table, its fields in SI units with
the unit in the name where the file's key has it.

A table is also a read-only mapping of the values it holds (``spec.motor["R"]``, ``"flux_map" in
spec.motor``, ``dict(spec.ratings)``): a field left None is absent, as it is from the file. Fields are
complete after [`pmsmjax.spec.drive_spec.complete`][pmsmjax.spec.drive_spec.complete]: every value the file
leaves out is derived there, so only the genuinely optional ones (a multi-phase motor's, an encoder's, the
tolerances the file gives) can be None.
"""

import dataclasses
from collections.abc import Iterator, Mapping

__all__ = [
    "Table",
    "MotorTable",
    "RatingsTable",
    "InverterTable",
    "SensorTable",
    "ToleranceTable",
    "ControlTable",
    "ScenarioTable",
    "TuningTable",
    "ThermalTable",
    "OperatingTable",
    "MechanicsTable",
    "HarmonicsTable",
]


@dataclasses.dataclass(frozen=True, eq=False)
class Table(Mapping):
    """A frozen table whose fields that are not None read as a mapping, in field order (equal to any
    mapping of the same items, as a dict is)."""

    def __getitem__(self, key: str):
        value = getattr(self, key) if key in self._names() else None
        if value is None:
            raise KeyError(key)
        return value

    def __iter__(self) -> Iterator[str]:
        return (name for name in self._names() if getattr(self, name) is not None)

    def __len__(self) -> int:
        return sum(1 for _ in self)

    @classmethod
    def _names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in dataclasses.fields(cls))

    @classmethod
    def of(cls, values: Mapping):
        """The table of ``values`` (a checked, completed dict of the file's table)."""
        return cls(**values)


@dataclasses.dataclass(frozen=True, eq=False)
class MotorTable(Table):
    """``[motor]``: the motor's linear model, SI units.

    Attributes:
        flux_map: the measured flux map's absolute path (three-phase), None without one; the grid itself
            is [`pmsmjax.spec.drive_spec.DriveSpec.flux_map`][pmsmjax.spec.drive_spec.DriveSpec].
        R: stator resistance per phase, ohm.
        L_d: d-axis inductance, H (with a flux map: the map's incremental one unless given).
        L_q: q-axis inductance, H.
        psi_f: permanent-magnet flux linkage, peak per phase, Wb.
        pole_pairs: pole-pair number.
        J: rotor inertia, kg m^2.
        B: viscous friction, N m s/rad.
        L_ls: leakage inductance of a six- or five-phase motor, H.
        psi_f3: third-harmonic magnet flux of a five-phase motor, Wb.
        n_phases: 6 or 5 for a multi-phase motor; None for three phases.
        reference_temperature_c: temperature at which ``R`` and ``psi_f`` hold, degC.
        r_temp_coeff_per_k: relative change of ``R`` per kelvin, 1/K (copper 0.00393).
        psi_f_temp_coeff_per_k: relative change of ``psi_f`` per kelvin, 1/K (NdFeB -0.001 to -0.0012).
    """

    flux_map: str | None = None
    R: float | None = None
    L_d: float | None = None
    L_q: float | None = None
    psi_f: float | None = None
    pole_pairs: int | None = None
    J: float | None = None
    B: float | None = None
    L_ls: float | None = None
    psi_f3: float | None = None
    n_phases: int | None = None
    reference_temperature_c: float | None = None
    r_temp_coeff_per_k: float | None = None
    psi_f_temp_coeff_per_k: float | None = None


@dataclasses.dataclass(frozen=True, eq=False)
class RatingsTable(Table):
    """``[ratings]``: rated speed (r/min), rated torque (N m), rated and maximum current (A peak)."""

    rated_speed_rpm: float
    rated_torque_nm: float
    rated_current_a: float
    max_current_a: float


@dataclasses.dataclass(frozen=True, eq=False)
class InverterTable(Table):
    """``[inverter]``: DC link (V), switching and control frequency (Hz), dead time (s), a device's
    on-state drop (V), and whether the controller compensates the last two."""

    u_dc_v: float
    switching_frequency_hz: float
    control_frequency_hz: float
    dead_time_s: float
    device_drop_v: float
    dead_time_compensation: bool


@dataclasses.dataclass(frozen=True, eq=False)
class SensorTable(Table):
    """``[sensor]``: ``kind`` (``"exact"`` or ``"encoder"``); an encoder's lines per mechanical revolution,
    latency (s) and mounting offset (electrical rad); the phase-current sensors' offsets (A) and gains, one
    per sensed phase a, b (, c), and ADC step (A), where the file gives them."""

    kind: str = "exact"
    lines: int | None = None
    delay_s: float | None = None
    encoder_offset_rad: float | None = None
    current_offset_a: tuple | None = None
    current_gain: tuple | None = None
    current_lsb_a: float | None = None


@dataclasses.dataclass(frozen=True, eq=False)
class ToleranceTable(Table):
    """``[tolerances]``: relative half-widths of the parameters' spread (0.05: +-5 %), only those the
    file gives; ``current_offset_a`` is absolute (A: 0.05 is +-50 mA on each current sensor) and
    ``current_gain`` relative on each sensor's gain."""

    R: float | None = None
    L_d: float | None = None
    L_q: float | None = None
    psi_f: float | None = None
    J: float | None = None
    B: float | None = None
    L_ls: float | None = None
    u_dc_v: float | None = None
    current_offset_a: float | None = None
    current_gain: float | None = None
    load_inertia: float | None = None
    shaft_stiffness_nm_per_rad: float | None = None


@dataclasses.dataclass(frozen=True, eq=False)
class ControlTable(Table):
    """``[control]``: current- and speed-loop bandwidths (rad/s) and the sensorless I/f start: current
    (A), acceleration (rad/s^2), hand-over speed and blend span (mechanical rad/s); the speed loop's
    optional filters: a low-pass on the speed feedback (Hz) and a notch on its output (centre and width
    Hz, depth dB), None when left out."""

    current_bandwidth_rad_s: float
    speed_bandwidth_rad_s: float
    startup_current_a: float
    startup_acceleration_rad_s2: float
    handover_speed_rad_s: float
    blend_speed_rad_s: float
    speed_filter_hz: float | None = None
    notch_hz: float | None = None
    notch_width_hz: float | None = None
    notch_depth_db: float | None = None


@dataclasses.dataclass(frozen=True, eq=False)
class ScenarioTable(Table):
    """``[scenario]``: a speed step from rest (r/min), a load step (N m) at ``load_time_s`` (s), the run's
    duration (s)."""

    speed_rpm: float
    load_nm: float
    load_time_s: float
    duration_s: float


@dataclasses.dataclass(frozen=True, eq=False)
class TuningTable(Table):
    """``[tuning]``: the ranges ``[low, high]`` tuning batches draw speeds (r/min), loads (N m) and
    durations (s) from."""

    speed_rpm: list
    load_nm: list
    duration_s: list


@dataclasses.dataclass(frozen=True, eq=False)
class ThermalTable(Table):
    """``[thermal]``: the winding's one-node thermal network, thermal resistance to ambient (K/W) and heat
    capacity (J/K), the ambient and the run's initial winding temperature (degC); empty (every field None)
    for a drive file without ``[thermal]`` (constant ``R`` and ``psi_f``)."""

    r_th_k_per_w: float | None = None
    c_th_j_per_k: float | None = None
    ambient_c: float | None = None
    initial_c: float | None = None


@dataclasses.dataclass(frozen=True, eq=False)
class OperatingTable(Table):
    """``[operating]``: what varies in use, as ranges ``[low, high]``: the winding temperature at the start
    of a run (degC), the DC link (V), the ambient (degC); only those the file gives. Monte Carlo studies
    and robust tuning draw from them, uniformly."""

    winding_temperature_c: list | None = None
    u_dc_v: list | None = None
    ambient_c: list | None = None


@dataclasses.dataclass(frozen=True, eq=False)
class MechanicsTable(Table):
    """``[mechanics]``: a compliant shaft between the motor (``[motor] J``) and its load: the load's inertia
    (kg m^2), the shaft's torsional stiffness (N m/rad) and damping (N m s/rad); empty (every field None)
    for a rigid shaft."""

    load_inertia: float | None = None
    shaft_stiffness_nm_per_rad: float | None = None
    shaft_damping_nm_s_per_rad: float | None = None


@dataclasses.dataclass(frozen=True, eq=False)
class HarmonicsTable(Table):
    """``[harmonics]``: magnet flux harmonics (``flux``, rows ``(order, amplitude Wb, phase rad)``) and
    cogging torque (``cogging``, rows ``(order, amplitude N m, phase rad)``), orders per electrical
    revolution ([`pmsmjax.spec.harmonics`][pmsmjax.spec.harmonics]); empty for a drive file without it."""

    flux: tuple | None = None
    cogging: tuple | None = None
