"""A drive log for identification: read any supported layout, convert to dq and SI units, check it.

The columns, their units and the column map are those of
[`tuning.identify.log_columns`][tuning.identify.log_columns]; stationary-frame signals need ``theta_e`` (to
turn them into dq).

The voltage of row k is the one applied from ``t_k`` to ``t_{k+1}``. Stationary-frame and duty voltages
are turned into dq with ``theta_e[k]``; how the voltage is held between rows (``hold``) is a property of
the recording, as in [`pmsmjax.recorded.replay`][pmsmjax.recorded.replay]: ``"stator"`` for a real inverter,
``"rotor"`` for a dq-model simulator, ``"auto"`` (the command's default) to find it from the log
([`tuning.identify.hold`][tuning.identify.hold]).

Checks, all before any fitting, each a [`ParameterError`][pmsmjax.spec.validation.ParameterError] naming the
column and the fix: missing or unknown columns (with close-name hints; a file column that looks like a
misspelt canonical one the log lacks, ``omgea_m``, is refused rather than left unused), NaN/inf,
non-increasing time ([`pmsmjax.io.logs.check_columns`][pmsmjax.io.logs.check_columns]), irregular sampling
inside a capture (refused, or resampled with a warning when asked), a sampling step too long for the
electrical dynamics, and a speed inconsistent with the angle (rpm in a rad/s column, electrical instead of
mechanical speed, wrong pole pairs).

**Bursts.** A log recorded in bursts (a scope's re-triggered captures, a firmware datalog buffer) has time
gaps longer than ``GAP_STEPS`` sampling steps between its captures; each capture becomes a segment
(`DriveLog.segments`) and nothing derived from the log spans a gap: a speed derived from the angle, an angle
integrated from the speed, the shooting windows and the equation-error blocks of the fit are all per capture.
"""

import dataclasses
import os
from pathlib import Path

import jax
import numpy as np

from pmsmjax.io.csv_dialect import CsvDialect
from pmsmjax.io.log_units import merge_units
from pmsmjax.io.logs import check_columns, misspelt_columns
from pmsmjax.io.toml_parser import read_toml
from pmsmjax.spec.validation import ParameterError
from tuning.identify.log_columns import (
    CANONICAL,
    CURRENT_SETS,
    MAX_STEP_S,
    MEANINGS,
    VOLTAGE_SETS,
    apply_units,
    check_grid,
    check_speed_against_angle,
    counts_to_angle,
    pick_set,
    read_canonical,
    segment_bounds,
    to_dq64,
)

__all__ = [
    "DriveLog",
    "load_drive_log",
    "drive_log_from_columns",
    "read_log_config",
    "CANONICAL",
]


@dataclasses.dataclass(frozen=True)
class DriveLog:
    """A log in dq and SI units; every array has one row per sample (``N`` rows).

    - `time`: ``(N,)`` s. `u_dq`: ``(N, 2)`` voltage applied from row k to k+1, V.
    - `i_dq`: ``(N, 2)`` A. `omega_m`: ``(N,)`` mechanical speed, rad/s. `theta_e`: ``(N,)`` rad
      (integrated from the speed, starting at 0, when the log has no angle).
    - `load_torque`: ``(N,)`` known load, N m (zeros when not logged).
    - `hold`: ``"stator"`` or ``"rotor"``; `source`: a name for messages; `notes`: what was derived.
    - `segments`: ``(S + 1,)`` row indices of the captures (capture ``s`` is rows
      ``segments[s]:segments[s + 1]``; ``[0, N]``, one capture, when not given).
    - `temperature_c`: ``(N,)`` winding temperature, degC, or None when not logged.
    """

    time: np.ndarray
    u_dq: np.ndarray
    i_dq: np.ndarray
    omega_m: np.ndarray
    theta_e: np.ndarray
    load_torque: np.ndarray
    hold: str = "stator"
    source: str = "log"
    notes: tuple[str, ...] = ()
    segments: np.ndarray | None = None
    temperature_c: np.ndarray | None = None

    def __post_init__(self):
        if self.segments is None:
            object.__setattr__(self, "segments", np.array([0, self.time.size]))

    @property
    def captures(self) -> int:
        """Number of captures (segments) in the log."""
        return int(self.segments.size - 1)

    @property
    def n(self) -> int:
        """Number of samples in the log."""
        return self.time.size


def read_log_config(path: str | os.PathLike) -> dict:
    """``{"columns": {...}, "units": {...}, "log": {...}}`` from a TOML file (missing tables empty)."""
    path = Path(path)
    if not path.is_file():
        raise ParameterError(f"log config {str(path)!r} does not exist: check the path.")
    data = read_toml(path, f"log config {path}")
    unknown = sorted(set(data) - {"columns", "units", "log", "identify"})
    if unknown:
        raise ParameterError(
            f"log config {path}: unknown tables {unknown}; allowed: [columns], [units], [log], [identify]."
        )
    return {k: dict(data.get(k, {})) for k in ("columns", "units", "log", "identify")}


def load_drive_log(
    path: str | os.PathLike,
    pole_pairs: int,
    *,
    columns: dict | None = None,
    units: dict | None = None,
    hold: str = "stator",
    u_dc: float | None = None,
    resample: bool = False,
    encoder_lines: int | None = None,
    counter_bits: int | None = None,
    dialect: CsvDialect | None = None,
) -> DriveLog:
    """Read a ``.csv``/``.npz``/``.mat`` log and return a checked [`DriveLog`][tuning.identify.log.DriveLog].

    `columns`: ``{canonical: name in file}``; `units`: ``{canonical or "current"/"voltage": unit}``;
    `hold`: ``"stator"`` (real inverter) or ``"rotor"`` (dq-model simulator); `u_dc`: DC-link voltage,
    V, for duty logs without a ``U_dc`` column; `resample`: resample an irregular time grid inside each
    capture onto a uniform one (with a warning) instead of refusing it; `encoder_lines`: lines per revolution
    of the encoder whose ``encoder_counts`` the log gives instead of ``theta_e``, `counter_bits`: the width of
    its counter when it wraps (else detected), see
    [`angle_from_counts`][tuning.identify.log_columns.angle_from_counts]; `dialect`: a CSV file's stated
    delimiter, decimal mark and header row ([`CsvDialect`][pmsmjax.io.csv_dialect.CsvDialect]). Units
    in the column names (``Time [ms]``) add to `units`.
    """
    unused: list[str] = []
    named: dict = {}
    present = read_canonical(path, columns, unused, dialect=dialect, named_units=named)
    units = merge_units(named, dict(units or {}), f"log {path}")
    wrong = misspelt_columns(unused, [c for c in CANONICAL if c not in present])
    if wrong:
        col, known = wrong[0]
        raise ParameterError(
            f"log {path}: column {col!r} is not a column identify reads; it looks like {known!r} "
            f"({MEANINGS[known]}), which the log lacks, so it would be identified without it: map it "
            f"(--columns {known}={col}) or rename it; rename or drop it if it is something else."
        )
    log = drive_log_from_columns(
        present,
        pole_pairs,
        units=units,
        hold=hold,
        u_dc=u_dc,
        resample=resample,
        source=f"log {path}",
        encoder_lines=encoder_lines,
        counter_bits=counter_bits,
    )
    if unused:
        log = dataclasses.replace(log, notes=log.notes + (f"columns not used: {', '.join(unused)}",))
    return log


def drive_log_from_columns(
    cols: dict,
    pole_pairs: int,
    *,
    units: dict | None = None,
    hold: str = "stator",
    u_dc: float | None = None,
    resample: bool = False,
    source: str = "log",
    encoder_lines: int | None = None,
    counter_bits: int | None = None,
) -> DriveLog:
    """Build a checked [`DriveLog`][tuning.identify.log.DriveLog] from canonical columns (NumPy arrays); see
    [`load_drive_log`][tuning.identify.log.load_drive_log]."""
    if not isinstance(pole_pairs, (int, np.integer)) or isinstance(pole_pairs, bool) or pole_pairs < 1:
        raise ParameterError(f"pole_pairs must be a positive integer (poles / 2), got {pole_pairs!r}.")
    if hold not in ("stator", "rotor", "auto"):
        raise ParameterError(
            f"hold must be 'stator' (real inverter), 'rotor' (dq-model simulator) or 'auto' (found from the "
            f"log), got {hold!r}."
        )
    vset = pick_set(cols, VOLTAGE_SETS, "voltage", source)
    two_sensors = "i_a" in cols and "i_b" in cols and "i_c" not in cols
    if two_sensors:  # two current sensors: the third current as the firmware computes it
        cols = {**cols, "i_c": -(np.asarray(cols["i_a"], float) + np.asarray(cols["i_b"], float))}
        if units and "i_a" in units:
            units = {**units, "i_c": units["i_a"]}
    iset = pick_set(cols, CURRENT_SETS, "current", source)
    need = ["time", *VOLTAGE_SETS[vset], *CURRENT_SETS[iset]]
    if vset == "duty" and u_dc is None:
        need.append("U_dc")
    if "theta_e" in cols and "encoder_counts" in cols:
        raise ParameterError(
            f"{source}: has both theta_e and encoder_counts, two angles: keep one (map the other away in the "
            "column map, or drop its column)."
        )
    angle = "encoder_counts" if "encoder_counts" in cols else "theta_e"
    if angle not in cols and "omega_m" not in cols:
        raise ParameterError(
            f"{source}: needs the rotor angle theta_e (electrical rad) and/or the speed omega_m (mechanical "
            "rad/s); neither column is present: add one or map its name in the column map."
        )
    if (vset != "dq" or iset != "dq") and angle not in cols:
        raise ParameterError(
            f"{source}: {vset if vset != 'dq' else iset} signals need the electrical angle theta_e to turn "
            "them into dq: add a theta_e column (rad) or log dq signals."
        )
    optional = [c for c in (angle, "omega_m", "T_L", "U_dc", "temperature_c") if c not in need]
    c = check_columns(cols, need, optional, source=source)
    apply_units(c, units or {}, source, pole_pairs)
    notes = ["i_c = -i_a - i_b (two current sensors)"] if two_sensors and iset == "abc" else []
    from_counts = counts_to_angle(c, pole_pairs, encoder_lines, counter_bits, source)
    if from_counts:
        notes.append(from_counts)
    dt = np.diff(c["time"])
    c, dt, resampled = check_grid(c, dt, resample, source, bursts=True)
    if resampled:
        notes.append(resampled)
    if np.median(dt) > MAX_STEP_S * (1.0 + 1e-9):  # a 1 ms step of a ms count, to rounding
        step = float(np.median(dt))
        unit = next((u for u, f in (("ms", 1e-3), ("us", 1e-6)) if step * f <= MAX_STEP_S), None)
        guess = (
            f"time looks like it is in {unit}: set its unit (--units time={unit}, or time = '{unit}' in "
            "[units])"
            if unit
            else "log faster"
        )
        raise ParameterError(
            f"{source}: sampling step {step:.3g} s is longer than {MAX_STEP_S:g} s; the current dynamics (a "
            f"few ms) need samples at 1 kHz or faster: {guess}."
        )

    if "theta_e" in c and "omega_m" in c:
        check_speed_against_angle(c, pole_pairs, source)
    bounds = segment_bounds(c["time"])
    per_capture = lambda f: np.concatenate([f(a, b) for a, b in zip(bounds[:-1], bounds[1:], strict=True)])
    if "omega_m" not in c:
        c["omega_m"] = per_capture(
            lambda a, b: np.gradient(np.unwrap(c["theta_e"][a:b]), c["time"][a:b]) / pole_pairs
        )
        notes.append("omega_m derived from the derivative of theta_e")
    if "theta_e" not in c:
        w_e = pole_pairs * c["omega_m"]

        def integral(a, b):
            w, h = w_e[a:b], np.diff(c["time"][a:b])
            return np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * h)])

        th = per_capture(integral)
        c["theta_e"] = np.mod(th + np.pi, 2 * np.pi) - np.pi
        start = "starting at 0" if bounds.size == 2 else "starting at 0 in each capture"
        notes.append(f"theta_e integrated from omega_m ({start})")

    th = c["theta_e"]
    u = _to_dq(c, VOLTAGE_SETS[vset], vset, th, u_dc)
    i = _to_dq(c, CURRENT_SETS[iset], iset, th, None)
    log = DriveLog(
        time=c["time"],
        u_dq=u,
        i_dq=i,
        omega_m=c["omega_m"],
        theta_e=th,
        load_torque=c.get("T_L", np.zeros_like(c["time"])),
        hold="stator" if hold == "auto" else hold,
        source=source,
        notes=tuple(notes),
        segments=bounds,
        temperature_c=c.get("temperature_c"),
    )
    if hold == "auto":
        from tuning.identify.hold import detect_hold

        log = detect_hold(log, pole_pairs)[0]
    return log


def _to_dq(c: dict, names, frame: str, th: np.ndarray, u_dc) -> np.ndarray:
    # The frame transforms are jnp functions: run them in float64 whatever the process default is.
    with jax.enable_x64(True):
        return to_dq64(c, names, frame, th, u_dc)
