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
non-increasing time ([`pmsmjax.io.logs.check_columns`][pmsmjax.io.logs.check_columns]), irregular sampling or
gaps (refused, or resampled with a warning when asked), a sampling step too long for the electrical dynamics,
and a speed inconsistent with the angle (rpm in a rad/s column, electrical instead of mechanical speed, wrong
pole pairs).
"""

import dataclasses
import os
from pathlib import Path

import jax
import numpy as np

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
    pick_set,
    read_canonical,
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
) -> DriveLog:
    """Read a ``.csv``/``.npz``/``.mat`` log and return a checked [`DriveLog`][tuning.identify.log.DriveLog].

    `columns`: ``{canonical: name in file}``; `units`: ``{canonical or "current"/"voltage": unit}``;
    `hold`: ``"stator"`` (real inverter) or ``"rotor"`` (dq-model simulator); `u_dc`: DC-link voltage,
    V, for duty logs without a ``U_dc`` column; `resample`: resample an irregular time grid onto a
    uniform one (with a warning) instead of refusing it.
    """
    unused: list[str] = []
    present = read_canonical(path, columns, unused)
    wrong = misspelt_columns(unused, [c for c in CANONICAL if c not in present])
    if wrong:
        col, known = wrong[0]
        raise ParameterError(
            f"log {path}: column {col!r} is not a column identify reads; it looks like {known!r} "
            f"({MEANINGS[known]}), which the log lacks, so it would be identified without it: map it "
            f"(--columns {known}={col}) or rename it; rename or drop it if it is something else."
        )
    log = drive_log_from_columns(
        present, pole_pairs, units=units, hold=hold, u_dc=u_dc, resample=resample, source=f"log {path}"
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
    iset = pick_set(cols, CURRENT_SETS, "current", source)
    need = ["time", *VOLTAGE_SETS[vset], *CURRENT_SETS[iset]]
    if vset == "duty" and u_dc is None:
        need.append("U_dc")
    if "theta_e" not in cols and "omega_m" not in cols:
        raise ParameterError(
            f"{source}: needs the rotor angle theta_e (electrical rad) and/or the speed omega_m (mechanical "
            "rad/s); neither column is present: add one or map its name in the column map."
        )
    if (vset != "dq" or iset != "dq") and "theta_e" not in cols:
        raise ParameterError(
            f"{source}: {vset if vset != 'dq' else iset} signals need the electrical angle theta_e to turn "
            "them into dq: add a theta_e column (rad) or log dq signals."
        )
    optional = [c for c in ("theta_e", "omega_m", "T_L", "U_dc") if c not in need]
    c = check_columns(cols, need, optional, source=source)
    apply_units(c, units or {}, source)
    notes = []
    dt = np.diff(c["time"])
    c, dt, resampled = check_grid(c, dt, resample, source)
    if resampled:
        notes.append(resampled)
    if np.median(dt) > MAX_STEP_S:
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
    if "omega_m" not in c:
        th = np.unwrap(c["theta_e"])
        c["omega_m"] = np.gradient(th, c["time"]) / pole_pairs
        notes.append("omega_m derived from the derivative of theta_e")
    if "theta_e" not in c:
        w_e = pole_pairs * c["omega_m"]
        th = np.concatenate([[0.0], np.cumsum(0.5 * (w_e[1:] + w_e[:-1]) * dt)])
        c["theta_e"] = np.mod(th + np.pi, 2 * np.pi) - np.pi
        notes.append("theta_e integrated from omega_m (starting at 0)")

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
    )
    if hold == "auto":
        from tuning.identify.hold import detect_hold

        log = detect_hold(log, pole_pairs)[0]
    return log


def _to_dq(c: dict, names, frame: str, th: np.ndarray, u_dc) -> np.ndarray:
    # The frame transforms are jnp functions: run them in float64 whatever the process default is.
    with jax.enable_x64(True):
        return to_dq64(c, names, frame, th, u_dc)
