"""A drive log for identification: read any supported layout, convert to dq and SI units, check it.

Column names in the file are mapped to canonical names by a column map (``{canonical: name in file}``,
from options or the ``[columns]`` table of a TOML file); units by ``{canonical: unit}`` (``[units]``).
Canonical columns (SI units after conversion):

- ``time`` (s; ``ms``, ``us`` accepted);
- voltages, one set: ``u_d, u_q`` | ``u_alpha, u_beta`` | ``u_a, u_b, u_c`` | duties ``d_a, d_b, d_c``
  (0..1) with ``U_dc`` (a column or the ``u_dc`` option), V;
- currents, one set: ``i_d, i_q`` | ``i_alpha, i_beta`` | ``i_a, i_b, i_c``, A (``mA``);
- ``theta_e`` electrical angle (rad; ``deg``) and/or ``omega_m`` mechanical speed (rad/s; ``rpm``,
  ``Hz`` = rev/s); stationary-frame signals need ``theta_e`` (to turn them into dq);
- ``T_L`` known load torque, N m (optional).

The voltage of row k is the one applied from ``t_k`` to ``t_{k+1}``. Stationary-frame and duty voltages
are turned into dq with ``theta_e[k]``; how the voltage is held between rows (``hold``) is a property of
the recording, as in [`pmsmjax.studies.replay`][pmsmjax.studies.replay]: ``"stator"`` for a real inverter,
``"rotor"`` for a dq-model simulator, ``"auto"`` (the command's default) to find it from the log
([`tuning.identify.hold`][tuning.identify.hold]).

Checks, all before any fitting, each a [`ParameterError`][pmsmjax.checks.validation.ParameterError] naming the
column and the fix: missing or unknown columns (with close-name hints; a file column that looks like a
misspelt canonical one the log lacks, ``omgea_m``, is refused rather than left unused), NaN/inf,
non-increasing time ([`pmsmjax.io.logs.check_columns`][pmsmjax.io.logs.check_columns]), irregular sampling or
gaps (refused, or resampled with a warning when asked), a sampling step too long for the electrical dynamics,
and a speed inconsistent with the angle (rpm in a rad/s column, electrical instead of mechanical speed, wrong
pole pairs).
"""

import dataclasses
import difflib
import os
import sys
import warnings
from pathlib import Path

import jax
import numpy as np

from pmsmjax.checks.validation import ParameterError
from pmsmjax.frames.three_phase import abc_to_alpha_beta, park
from pmsmjax.inverters.averaged import phase_voltages
from pmsmjax.io.logs import check_columns, column_names, misspelt_columns, read_log

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = [
    "DriveLog",
    "load_drive_log",
    "drive_log_from_columns",
    "read_log_config",
    "CANONICAL",
    "StatorLog",
    "load_stator_log",
    "stator_log_from_columns",
]

_VOLTAGE_SETS = {
    "dq": ("u_d", "u_q"),
    "alpha_beta": ("u_alpha", "u_beta"),
    "abc": ("u_a", "u_b", "u_c"),
    "duty": ("d_a", "d_b", "d_c"),
}
_CURRENT_SETS = {"dq": ("i_d", "i_q"), "alpha_beta": ("i_alpha", "i_beta"), "abc": ("i_a", "i_b", "i_c")}
#: Every canonical column name.
CANONICAL = (
    ("time", "theta_e", "omega_m", "T_L", "U_dc")
    + sum(_VOLTAGE_SETS.values(), ())
    + sum(_CURRENT_SETS.values(), ())
)
#: What each canonical column is, for messages.
MEANINGS = {
    "time": "time, s",
    "theta_e": "electrical rotor angle, rad",
    "omega_m": "mechanical speed, rad/s",
    "T_L": "known load torque, N m",
    "U_dc": "DC-link voltage, V",
    **{c: "voltage, V" for c in sum(_VOLTAGE_SETS.values(), ()) if not c.startswith("d_")},
    **{c: "duty cycle, 0..1" for c in _VOLTAGE_SETS["duty"]},
    **{c: "current, A" for c in sum(_CURRENT_SETS.values(), ())},
}
#: Accepted units: canonical column (or group) -> {unit: factor to SI}.
_UNITS = {
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6},
    "omega_m": {"rad/s": 1.0, "rpm": np.pi / 30.0, "Hz": 2.0 * np.pi},
    "theta_e": {"rad": 1.0, "deg": np.pi / 180.0},
    "current": {"A": 1.0, "mA": 1e-3},
    "voltage": {"V": 1.0, "mV": 1e-3, "kV": 1e3},
    "T_L": {"N m": 1.0, "Nm": 1.0},
}
#: Sampling steps deviating more than this from the median are irregular (refused or resampled).
MAX_JITTER = 0.05
#: Longest sampling step accepted, s: the electrical time constants of drives are a few ms.
MAX_STEP_S = 1e-3


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
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as err:
        raise ParameterError(f"log config {path}: not valid TOML ({err}).") from err
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
    present = _read_canonical(path, columns, unused)
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


def _read_canonical(path, columns: dict | None, unused: list | None = None) -> dict:
    """The canonical columns present in the log at ``path``, read through the column map ``columns``;
    the file's other column names are appended to ``unused`` when a list is given."""
    columns = dict(columns or {})
    bad = sorted(set(columns) - set(CANONICAL))
    if bad:
        hints = [f"{b!r} -> {difflib.get_close_matches(b, CANONICAL, 1, 0.5)}" for b in bad]
        raise ParameterError(
            f"column map: unknown canonical name(s) {bad} ({'; '.join(hints)}); the keys of [columns] "
            f"are canonical names ({', '.join(CANONICAL)}), the values the names in the file."
        )
    wanted = [columns.get(c, c) for c in CANONICAL]
    raw = read_log(path, (), wanted, time=None, unused=unused)
    back = {columns.get(c, c): c for c in CANONICAL}
    present = {back[k]: v for k, v in raw.items()}
    if not present:
        raise ParameterError(
            f"log {path}: none of the expected columns is present ({', '.join(CANONICAL)}); map the "
            "file's names with a column map (--columns or a [columns] table)."
        )
    return present


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
    vset = _pick_set(cols, _VOLTAGE_SETS, "voltage", source)
    iset = _pick_set(cols, _CURRENT_SETS, "current", source)
    need = ["time", *_VOLTAGE_SETS[vset], *_CURRENT_SETS[iset]]
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
    _apply_units(c, units or {}, source)
    notes = []
    dt = np.diff(c["time"])
    c, dt, resampled = _check_grid(c, dt, resample, source)
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
        _check_speed_against_angle(c, pole_pairs, source)
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
    u = _to_dq(c, _VOLTAGE_SETS[vset], vset, th, u_dc)
    i = _to_dq(c, _CURRENT_SETS[iset], iset, th, None)
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


def _pick_set(cols, sets, what, source) -> str:
    complete = [k for k, names in sets.items() if all(n in cols for n in names)]
    if complete:
        return complete[0]
    partial = {
        k: [n for n in names if n not in cols] for k, names in sets.items() if any(n in cols for n in names)
    }
    options = " | ".join(",".join(n) for n in sets.values())
    if partial:
        k, lack = next(iter(partial.items()))
        raise ParameterError(
            f"{source}: {what}s in {k} are incomplete, {', '.join(lack)} missing; log one full set "
            f"({options}) or map the names with a column map."
        )
    close = sorted(
        {m for n in sum(sets.values(), ()) for m in difflib.get_close_matches(n, list(cols), 1, 0.7)}
    )
    raise ParameterError(
        f"{source}: no {what} columns; expected one set of {options}"
        + (f" (columns {close} look close: map them with a column map)" if close else "")
        + "."
    )


def _apply_units(c: dict, units: dict, source: str) -> None:
    for key, unit in units.items():
        group = key if key in _UNITS else None
        if key in ("current", "voltage"):
            targets = [n for n in c if n.startswith("i_" if key == "current" else "u_")]
        elif key in _UNITS:
            targets = [key] if key in c else []
        elif key.startswith("i_") or key.startswith("u_"):
            group, targets = ("current" if key.startswith("i_") else "voltage"), [key] if key in c else []
        else:
            raise ParameterError(
                f"units: unknown key {key!r}; use time, omega_m, theta_e, T_L, current, voltage or a column."
            )
        table = _UNITS[group]
        if unit not in table:
            raise ParameterError(f"units: {key} = {unit!r} is not one of {', '.join(table)}.")
        for n in targets:
            c[n] = c[n] * table[unit]


def _check_grid(c: dict, dt: np.ndarray, resample: bool, source: str):
    """Refuse (or resample) an irregular time grid; returns ``(columns, dt, note or None)``."""
    med = float(np.median(dt))
    dev = np.abs(dt / med - 1.0)
    if dev.max() <= MAX_JITTER:
        return c, dt, None
    row = int(np.argmax(dev)) + 1
    reason = (
        f"the sampling is irregular: the step before row {row} (t = {c['time'][row]:.6g} s) is "
        f"{dt[row - 1]:.3g} s against a median of {med:.3g} s"
        + (f"; {int(np.sum(dt > 1.5 * med))} gap(s) longer than 1.5 steps" if np.any(dt > 1.5 * med) else "")
    )
    if not resample:
        raise ParameterError(
            f"{source}: {reason}. Cut the log at the gap, or pass resample=True (--resample) to interpolate "
            "every signal onto a uniform grid (this also interpolates across gaps, which invents data there)."
        )
    t_new = c["time"][0] + med * np.arange(int(np.floor((c["time"][-1] - c["time"][0]) / med)) + 1)
    out = {}
    for name, v in c.items():
        if name == "theta_e":
            th = np.interp(t_new, c["time"], np.unwrap(v))
            out[name] = np.mod(th + np.pi, 2 * np.pi) - np.pi
        else:
            out[name] = np.interp(t_new, c["time"], v)
    note = f"resampled onto a uniform {med:.3g} s grid: {reason}"
    warnings.warn(f"{source}: {note}", stacklevel=3)
    return out, np.diff(t_new), note


def _check_speed_against_angle(c: dict, pole_pairs: int, source: str) -> None:
    """The angle's rate of change must be ``pole_pairs * omega_m``; name the likely mistake otherwise."""
    t, th, w = c["time"], np.unwrap(c["theta_e"]), pole_pairs * c["omega_m"]
    step = max(1, th.size // 2000)  # differences over several samples: quantised angles stay usable
    rate = np.diff(th[::step]) / np.diff(t[::step])
    w_mid = 0.5 * (w[::step][1:] + w[::step][:-1])
    if np.sqrt(np.mean(w_mid**2)) < 1.0 or np.sqrt(np.mean(rate**2)) < 1.0:
        return  # (nearly) standstill: nothing to compare
    ratio = float(np.dot(rate, w_mid) / np.dot(w_mid, w_mid))
    if abs(ratio - 1.0) < 0.1:
        return
    guesses = (  # (ratio the mistake produces, what to do)
        (np.pi / 30.0, "omega_m looks like r/min: set units omega_m = 'rpm'"),
        (2.0 * np.pi, "omega_m looks like rev/s: set units omega_m = 'Hz'"),
        (1.0 / pole_pairs, "omega_m looks like the electrical speed (divide it by the pole pairs), or "
         "theta_e like the mechanical angle (multiply it by the pole pairs)"),
        (-1.0, "theta_e and omega_m have opposite signs: flip one of them"),
    )  # fmt: skip
    hint = next(
        (h for r, h in guesses if r * ratio > 0 and abs(np.log(ratio / r)) < 0.15),
        f"check the units of omega_m (mechanical rad/s), of theta_e (electrical rad) and the pole pairs "
        f"({pole_pairs}; the ratio suggests {pole_pairs * ratio:.3g})",
    )
    raise ParameterError(
        f"{source}: the angle theta_e turns at {ratio:.4g} x pole_pairs x omega_m, not 1 x: {hint}."
    )


def _to_dq(c: dict, names, frame: str, th: np.ndarray, u_dc) -> np.ndarray:
    # The frame transforms are jnp functions: run them in float64 whatever the process default is.
    with jax.enable_x64(True):
        return _to_dq64(c, names, frame, th, u_dc)


def _to_dq64(c: dict, names, frame: str, th: np.ndarray, u_dc) -> np.ndarray:
    if frame == "dq":
        return np.stack([c[names[0]], c[names[1]]], axis=1)
    if frame == "alpha_beta":
        ab = np.stack([c[names[0]], c[names[1]]], axis=1)
    elif frame == "abc":
        ab = np.asarray(abc_to_alpha_beta(np.stack([c[n] for n in names], axis=1)))
    else:  # duties: period-average phase voltages of the bridge
        vdc = c["U_dc"][:, None] if "U_dc" in c else float(u_dc)
        duties = np.stack([c[n] for n in names], axis=1)
        if duties.min() < -1e-9 or duties.max() > 1 + 1e-9:
            raise ParameterError(
                f"duty columns {', '.join(names)} must lie in [0, 1], got {duties.min():.3g} to "
                f"{duties.max():.3g}: give duties as fractions (percent / 100)."
            )
        ab = np.asarray(abc_to_alpha_beta(np.asarray(phase_voltages(duties, vdc))))
    return np.asarray(park(ab, th), dtype=np.float64)


# --------------------------------------------------------------------------------------------------
# stationary-frame logs (observers: pmsmjax observe)
# --------------------------------------------------------------------------------------------------
#: Signal sets an observer can use: it estimates the angle, so it needs stator-frame signals.
_STATOR_VOLTAGE_SETS = {k: v for k, v in _VOLTAGE_SETS.items() if k != "dq"}
_STATOR_CURRENT_SETS = {k: v for k, v in _CURRENT_SETS.items() if k != "dq"}
#: Columns a log may offer as the truth an observer is scored against.
TRUTH = ("theta_e", "omega_m")


@dataclasses.dataclass(frozen=True)
class StatorLog:
    """A log in the stationary frame and SI units, for an observer (``N`` rows).

    - `time`: ``(N,)`` s, uniform with step `Ts` (s). `u_ab`: ``(N, 2)`` voltage applied from row k to k+1,
      V. `i_ab`: ``(N, 2)`` current sampled at row k, A.
    - `truth`: the requested truth columns (``theta_e`` electrical rad, ``omega_m`` mechanical rad/s).
    - `source`: a name for messages; `notes`: what was derived.
    """

    time: np.ndarray
    u_ab: np.ndarray
    i_ab: np.ndarray
    Ts: float
    truth: dict
    source: str = "log"
    notes: tuple[str, ...] = ()

    @property
    def n(self) -> int:
        """Number of samples in the log."""
        return self.time.size


def load_stator_log(
    path: str | os.PathLike,
    *,
    columns: dict | None = None,
    units: dict | None = None,
    u_dc: float | None = None,
    resample: bool = False,
    truth: tuple[str, ...] = (),
    pole_pairs: int | None = None,
) -> StatorLog:
    """Read a ``.csv``/``.npz``/``.mat`` log for an observer and return a checked
    [`StatorLog`][tuning.identify.log.StatorLog].

    Voltages ``u_alpha, u_beta`` | ``u_a, u_b, u_c`` | duties ``d_a, d_b, d_c`` with ``U_dc`` (or `u_dc`,
    V); currents ``i_alpha, i_beta`` | ``i_a, i_b, i_c``; other columns are ignored unless named in
    `truth` (a subset of ``theta_e``, ``omega_m``). `columns`, `units`, `resample`: as
    [`load_drive_log`][tuning.identify.log.load_drive_log]; `pole_pairs` (when both truth columns are given)
    checks the speed against the angle.
    """
    bad = [c for c in truth if c not in TRUTH]
    if bad:
        hints = [f"{b!r} -> {difflib.get_close_matches(b, TRUTH, 1, 0.5) or 'no close name'}" for b in bad]
        raise ParameterError(
            f"truth columns: unknown {bad} ({'; '.join(hints)}); the truth an observer is scored against is "
            f"theta_e (electrical rad) and/or omega_m (mechanical rad/s); map the file's names with a column "
            "map (e.g. theta_e=angle)."
        )
    present = _read_canonical(path, columns)
    unmapped = sorted(set(column_names(path)) - set(present) - set((columns or {}).values()))
    return stator_log_from_columns(
        present, units=units, u_dc=u_dc, resample=resample, truth=truth, pole_pairs=pole_pairs,
        source=f"log {path}", other_columns=unmapped,
    )  # fmt: skip


def stator_log_from_columns(
    cols: dict,
    *,
    units: dict | None = None,
    u_dc: float | None = None,
    resample: bool = False,
    truth: tuple[str, ...] = (),
    pole_pairs: int | None = None,
    source: str = "log",
    other_columns: list[str] = (),
) -> StatorLog:
    """A checked [`StatorLog`][tuning.identify.log.StatorLog] from canonical columns (NumPy arrays); see
    [`load_stator_log`][tuning.identify.log.load_stator_log]. `other_columns`: the file's other column names,
    searched for close matches of missing ones."""
    if not any(n in cols for n in sum(_STATOR_VOLTAGE_SETS.values(), ())) and all(
        n in cols for n in _VOLTAGE_SETS["dq"]
    ):
        raise ParameterError(
            f"{source}: the voltages are logged in dq (u_d, u_q), which needs the rotor angle that the "
            "observer is to estimate: log the stator-frame voltages (u_alpha,u_beta or u_a,u_b,u_c or duties "
            "d_a,d_b,d_c)."
        )
    if not any(n in cols for n in sum(_STATOR_CURRENT_SETS.values(), ())) and all(
        n in cols for n in _CURRENT_SETS["dq"]
    ):
        raise ParameterError(
            f"{source}: the currents are logged in dq (i_d, i_q), which needs the rotor angle that the "
            "observer is to estimate: log the stator-frame currents (i_alpha,i_beta or i_a,i_b,i_c)."
        )
    try:
        vset = _pick_set(cols, _STATOR_VOLTAGE_SETS, "voltage", source)
        iset = _pick_set(cols, _STATOR_CURRENT_SETS, "current", source)
    except ParameterError as err:
        raise ParameterError(f"{err}{_hints(cols, other_columns)}") from None
    need = ["time", *_STATOR_VOLTAGE_SETS[vset], *_STATOR_CURRENT_SETS[iset], *truth]
    missing = [n for n in need if n not in cols and n != "U_dc"]
    if missing:
        raise ParameterError(
            f"{source}: missing column(s) {', '.join(missing)}; present: {', '.join(sorted(cols))}. Add them "
            f"or map the file's names with a column map{_hints(cols, other_columns, missing)}."
        )
    if vset == "duty" and u_dc is None:
        need.append("U_dc")
    optional = ["U_dc"] if vset == "duty" and "U_dc" not in need else []
    c = check_columns(cols, need, optional, source=source)
    _apply_units(c, units or {}, source)
    notes = []
    c, dt, resampled = _check_grid(c, np.diff(c["time"]), resample, source)
    if resampled:
        notes.append(resampled)
    Ts = float(np.median(dt))
    if Ts > MAX_STEP_S:
        raise ParameterError(
            f"{source}: sampling step {Ts:.3g} s is longer than {MAX_STEP_S:g} s; an observer needs the "
            "control-period samples (1 kHz or faster). If time is not in seconds, set its unit "
            "(--units time=ms or time=us)."
        )
    if "theta_e" in truth and "omega_m" in truth and pole_pairs is not None:
        _check_speed_against_angle(c, pole_pairs, source)
    with jax.enable_x64(True):
        u = _to_alpha_beta64(c, _STATOR_VOLTAGE_SETS[vset], vset, u_dc)
        i = _to_alpha_beta64(c, _STATOR_CURRENT_SETS[iset], iset, None)
    return StatorLog(
        time=c["time"],
        u_ab=u,
        i_ab=i,
        Ts=Ts,
        truth={k: c[k] for k in truth},
        source=source,
        notes=tuple(notes),
    )


def _hints(cols: dict, other_columns, missing=None) -> str:
    """`` (hint: ...)`` naming file columns close to the missing canonical ones, or ``""``. Without
    `missing`: the names lacking from partially logged signal sets (or from every set when none is)."""
    if missing is None:
        missing = []
        for sets in (_STATOR_VOLTAGE_SETS, _STATOR_CURRENT_SETS):
            partial = [names for names in sets.values() if any(n in cols for n in names)]
            candidates = partial or [names for k, names in sets.items() if k != "duty"]
            missing += [n for names in candidates for n in names if n not in cols]
    pairs = []
    for name in missing:
        close = difflib.get_close_matches(name, list(other_columns), n=1, cutoff=0.6)
        if close:
            pairs.append(f"{close[0]!r} looks like {name!r}: map it with {name}={close[0]}")
    return f" (hint: {'; '.join(pairs)})" if pairs else ""


def _to_alpha_beta64(c: dict, names, frame: str, u_dc) -> np.ndarray:
    if frame == "alpha_beta":
        return np.stack([c[names[0]], c[names[1]]], axis=1)
    # abc and duties as for dq, without the rotation: turn them into dq at angle 0 (= alpha-beta).
    return _to_dq64(c, names, frame, np.zeros_like(c["time"]), u_dc)
