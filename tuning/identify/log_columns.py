"""The canonical columns of a drive log, shared by the identification log
([`tuning.identify.log`][tuning.identify.log]) and the observers' stator-frame log
([`tuning.identify.stator_log`][tuning.identify.stator_log]): their names, units and meanings, reading them
through a column map, and the checks and conversions both logs make.

Column names in the file are mapped to canonical names by a column map (``{canonical: name in file}``,
from options or the ``[columns]`` table of a TOML file); units by ``{canonical: unit}`` (``[units]``) or
by the names (``Time [ms]``, ``i_a (A)``, ``Ia/mA``: [`pmsmjax.io.log_units`][pmsmjax.io.log_units]).
Duties may be in ``%``.
Canonical columns (SI units after conversion):

- ``time`` (s; ``ms``, ``us`` accepted);
- voltages, one set: ``u_d, u_q`` | ``u_alpha, u_beta`` | ``u_a, u_b, u_c`` | duties ``d_a, d_b, d_c``
  (0..1) with ``U_dc`` (a column or the ``u_dc`` option), V;
- currents, one set: ``i_d, i_q`` | ``i_alpha, i_beta`` | ``i_a, i_b, i_c`` (or ``i_a, i_b`` of two sensors,
  ``i_c = -i_a - i_b``), A (``mA``);
- ``theta_e`` electrical angle (rad; ``deg``) and/or ``omega_m`` mechanical speed (rad/s; ``rpm``,
  ``Hz`` = rev/s, ``erpm`` = electrical r/min as VESC logs it);
- ``encoder_counts`` instead of ``theta_e``: an incremental encoder's quadrature count (4 per line), turned
  into ``theta_e`` by [`angle_from_counts`][tuning.identify.log_columns.angle_from_counts] with the encoder's
  lines per revolution. Its zero is the encoder's index, not the rotor's d axis: the offset between them is
  what ``identify --sensor-errors`` fits; without that fit it must be zero or compensated in the count;
- ``T_L`` known load torque, N m (optional);
- ``temperature_c`` winding temperature, degC (optional: R and psi_f as functions of it, their coefficients
  and the thermal network).

Each check raises a [`ParameterError`][pmsmjax.spec.validation.ParameterError] naming the column and the fix.
"""

import difflib
import warnings

import numpy as np

from pmsmjax.frames.three_phase import abc_to_alpha_beta, park
from pmsmjax.inverters.averaged import phase_voltages
from pmsmjax.io.csv_dialect import CsvDialect
from pmsmjax.io.log_formats import PresetColumn
from pmsmjax.io.log_units import UNITS as _UNITS
from pmsmjax.io.log_units import apply_units as _apply_units
from pmsmjax.io.logs import column_names, read_log
from pmsmjax.io.mapped_logs import resolve_columns
from pmsmjax.spec.validation import ParameterError

__all__ = [
    "CANONICAL",
    "CURRENT_SETS",
    "GAP_STEPS",
    "MAX_JITTER",
    "MIN_CAPTURE_ROWS",
    "MAX_STEP_S",
    "MEANINGS",
    "UNITS",
    "VOLTAGE_SETS",
    "apply_units",
    "check_grid",
    "segment_bounds",
    "check_speed_against_angle",
    "angle_from_counts",
    "counts_to_angle",
    "COUNTER_BITS",
    "pick_set",
    "read_canonical",
    "to_dq64",
]

#: The signal sets a log may give its voltages in (frame -> columns).
VOLTAGE_SETS = {
    "dq": ("u_d", "u_q"),
    "alpha_beta": ("u_alpha", "u_beta"),
    "abc": ("u_a", "u_b", "u_c"),
    "duty": ("d_a", "d_b", "d_c"),
}
#: The signal sets a log may give its currents in.
CURRENT_SETS = {"dq": ("i_d", "i_q"), "alpha_beta": ("i_alpha", "i_beta"), "abc": ("i_a", "i_b", "i_c")}
#: Every canonical column name.
CANONICAL = (
    ("time", "theta_e", "omega_m", "T_L", "U_dc", "encoder_counts", "temperature_c")
    + sum(VOLTAGE_SETS.values(), ())
    + sum(CURRENT_SETS.values(), ())
)
#: What each canonical column is, for messages.
MEANINGS = {
    "time": "time, s",
    "theta_e": "electrical rotor angle, rad",
    "omega_m": "mechanical speed, rad/s",
    "T_L": "known load torque, N m",
    "U_dc": "DC-link voltage, V",
    "encoder_counts": "incremental encoder count, 4 per line",
    "temperature_c": "winding temperature, degC",
    **{c: "voltage, V" for c in sum(VOLTAGE_SETS.values(), ()) if not c.startswith("d_")},
    **{c: "duty cycle, 0..1" for c in VOLTAGE_SETS["duty"]},
    **{c: "current, A" for c in sum(CURRENT_SETS.values(), ())},
}
#: Accepted units: canonical column (or group) -> {unit: factor to SI}
#: ([`pmsmjax.io.log_units`][pmsmjax.io.log_units]).
UNITS = _UNITS
#: Sampling steps deviating more than this from the median are irregular (refused or resampled).
MAX_JITTER = 0.05
#: A step longer than this many median steps is a gap between two captures of a burst log.
GAP_STEPS = 1.5
#: Fewest rows a capture of a burst log may have.
MIN_CAPTURE_ROWS = 20
#: Longest sampling step accepted, s: the electrical time constants of drives are a few ms.
MAX_STEP_S = 1e-3
#: Widths of the hardware counters whose wrap is recognised in an encoder count (16- and 32-bit timers).
COUNTER_BITS = (16, 32)


def read_canonical(
    path,
    columns: dict | None,
    unused: list | None = None,
    *,
    dialect: CsvDialect | None = None,
    named_units: dict | None = None,
) -> dict:
    """The canonical columns present in the log at ``path``, read through the column map ``columns``
    (names with unit suffixes matched as [`pmsmjax.io.mapped_logs`][pmsmjax.io.mapped_logs] does); the
    file's other column names are appended to ``unused`` when a list is given, and the units the matched
    names carry to ``named_units`` (``{canonical: unit}``) when a dict is given. `dialect`: a CSV file's
    stated delimiter, decimal mark and header row."""
    columns = dict(columns or {})
    bad = sorted(set(columns) - set(CANONICAL))
    if bad:
        hints = [f"{b!r} -> {difflib.get_close_matches(b, CANONICAL, 1, 0.5)}" for b in bad]
        raise ParameterError(
            f"column map: unknown canonical name(s) {bad} ({'; '.join(hints)}); the keys of [columns] "
            f"are canonical names ({', '.join(CANONICAL)}), the values the names in the file."
        )
    found, units = resolve_columns(column_names(path, dialect), CANONICAL, columns, f"log {path}")
    to_file = {c: found.get(c, columns.get(c, c)) for c in CANONICAL}
    unused = [] if unused is None else unused
    raw = read_log(path, (), list(to_file.values()), time=None, unused=unused, dialect=dialect)
    absent = [
        (c, name)
        for c, name in columns.items()
        if to_file[c] not in raw and not isinstance(name, PresetColumn)
    ]
    if absent:
        c, name = absent[0]
        listed = ", ".join(sorted({*raw, *unused})) or "none"
        raise ParameterError(
            f"column map {c}={name}: log {path} has no column {name!r} (its columns: {listed}): map {c} to "
            f'a column the log has (--columns {c}=NAME, or [columns] {c} = "NAME"), or drop the mapping.'
        )
    back = {n: c for c, n in to_file.items()}
    present = {back[k]: v for k, v in raw.items()}
    if not present:
        raise ParameterError(
            f"log {path}: none of the expected columns is present ({', '.join(CANONICAL)}); map the "
            "file's names with a column map (--columns or a [columns] table)."
        )
    if named_units is not None:
        named_units.update({c: u for c, u in units.items() if c in present})
    return present


def pick_set(cols, sets, what, source) -> str:
    """The first of ``sets`` (``{name: column names}``) whose columns ``cols`` all has; else a one-line
    refusal naming ``what`` is missing from ``source``."""
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


def apply_units(c: dict, units: dict, source: str, pole_pairs: int | None = None) -> None:
    """Convert the columns of ``c`` in place to SI by ``units`` (``{column or group: unit}``; ``erpm`` needs
    `pole_pairs`): [`pmsmjax.io.log_units.apply_units`][pmsmjax.io.log_units.apply_units]."""
    _apply_units(c, units, source, pole_pairs)


def segment_bounds(time: np.ndarray) -> np.ndarray:
    """``(S + 1,)`` row indices of the captures in a log recorded in bursts: capture ``s`` is rows
    ``bounds[s]:bounds[s + 1]``. A step longer than ``GAP_STEPS`` median steps is a gap between two captures
    (a re-triggered scope, a firmware datalog buffer); a log without gaps is one capture."""
    dt = np.diff(time)
    med = float(np.median(dt)) if dt.size else 0.0
    gaps = np.flatnonzero(dt > GAP_STEPS * med) + 1
    return np.concatenate([[0], gaps, [time.size]]).astype(int)


def check_grid(c: dict, dt: np.ndarray, resample: bool, source: str, bursts: bool = False):
    """Refuse (or resample) an irregular time grid; returns ``(columns, dt, note or None)``.

    With ``bursts``, a gap longer than ``GAP_STEPS`` median steps separates two captures
    ([`segment_bounds`][tuning.identify.log_columns.segment_bounds]) and only the sampling inside each capture
    must be regular; each capture needs ``MIN_CAPTURE_ROWS`` rows. The note then names the captures."""
    if not bursts:
        return _check_regular(c, dt, resample, source)
    bounds = segment_bounds(c["time"])
    short = [(a, b) for a, b in zip(bounds[:-1], bounds[1:], strict=True) if b - a < MIN_CAPTURE_ROWS]
    if short:
        a, b = short[0]
        raise ParameterError(
            f"{source}: the capture at rows {a + 1}..{b} (t = {c['time'][a]:.6g} s) has {b - a} row(s), "
            f"fewer than {MIN_CAPTURE_ROWS}: a time gap longer than {GAP_STEPS:g} sampling steps starts "
            "a new capture; drop the stray rows or record longer captures."
        )
    parts, notes = [], []
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        part = {n: v[a:b] for n, v in c.items()}
        part, _, note = _check_regular(part, np.diff(part["time"]), resample, source)
        parts.append(part)
        notes += [note] if note else []
    out = {n: np.concatenate([p[n] for p in parts]) for n in c}
    n_caps = len(parts)
    if n_caps > 1:
        gaps = np.diff(c["time"])[bounds[1:-1] - 1]
        notes.append(
            f"{n_caps} captures separated by time gaps ({gaps.min():.3g} to {gaps.max():.3g} s) fitted as "
            "separate segments: no window or block spans a gap"
        )
    return out, np.diff(out["time"]), "; ".join(notes) or None


def _check_regular(c: dict, dt: np.ndarray, resample: bool, source: str):
    """[`check_grid`][tuning.identify.log_columns.check_grid] for one capture."""
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


def check_speed_against_angle(c: dict, pole_pairs: int, source: str) -> None:
    """The angle's rate of change must be ``pole_pairs * omega_m`` (compared inside each capture of a burst
    log); name the likely mistake otherwise."""
    step = max(1, c["time"].size // 2000)  # differences over several samples: quantised angles stay usable
    bounds = segment_bounds(c["time"])
    rates, mids = [], []
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):  # no difference spans a gap between captures
        t, th, w = c["time"][a:b], np.unwrap(c["theta_e"][a:b]), pole_pairs * c["omega_m"][a:b]
        rates.append(np.diff(th[::step]) / np.diff(t[::step]))
        mids.append(0.5 * (w[::step][1:] + w[::step][:-1]))
    rate, w_mid = np.concatenate(rates), np.concatenate(mids)
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


def to_dq64(c: dict, names, frame: str, th: np.ndarray, u_dc) -> np.ndarray:
    """The ``(N, 2)`` float64 dq pair of columns ``names`` given in ``frame`` (dq, alpha-beta or phases),
    turned with the angle ``th`` (rad)."""
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


def angle_from_counts(
    counts, lines: int, pole_pairs: int, counter_bits: int | None = None, bounds=None
) -> np.ndarray:
    """``theta_e = pole_pairs * 2 pi * counts / (4 lines)``, electrical rad wrapped to (-pi, pi].

    `counts`: an incremental encoder's quadrature count (4 per line, zero at its index); `lines`: lines per
    mechanical revolution. A count from a hardware counter that wraps is unwrapped first: with
    `counter_bits` its width; without, a count whose values fit a 16- or 32-bit counter
    ([`COUNTER_BITS`][tuning.identify.log_columns.COUNTER_BITS], signed or unsigned) and that jumps by more
    than half of it between two rows is taken as wrapping there. `bounds`: the ``(S + 1,)`` first rows of the
    captures of a burst log ([`segment_bounds`][tuning.identify.log_columns.segment_bounds]); the count is
    unwrapped inside each capture only (how often the counter wrapped in a gap is unknown)."""
    counts = np.asarray(counts, dtype=np.float64)
    bounds = np.array([0, counts.size]) if bounds is None else np.asarray(bounds, dtype=int)
    bits = counter_bits if counter_bits is not None else _detected_bits(counts, bounds)
    if bits is not None and counts.size > 1:
        m = float(2**bits)
        parts = []
        for a, b in zip(bounds[:-1], bounds[1:], strict=True):
            d = np.diff(counts[a:b])
            d = d - m * np.round(d / m)
            parts.append(counts[a] + np.concatenate([[0.0], np.cumsum(d)]))
        counts = np.concatenate(parts)
    per_rev = 4.0 * lines
    mech = np.mod(counts, per_rev) / per_rev  # fraction of a mechanical revolution, exact for integers
    th = np.mod(pole_pairs * mech, 1.0) * (2.0 * np.pi)  # [0, 2 pi)
    return np.where(th > np.pi, th - 2.0 * np.pi, th)


def _detected_bits(counts: np.ndarray, bounds: np.ndarray) -> int | None:
    """The width of the counter a count wraps in (a jump of more than half of it inside a capture), or None
    when it does not wrap."""
    steps = [np.abs(np.diff(counts[a:b])) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
    jump = max((float(s.max()) for s in steps if s.size), default=0.0)
    lo, hi = counts.min(), counts.max()
    for bits in COUNTER_BITS:
        m = 2.0**bits
        if (0 <= lo and hi < m) or (-m / 2 <= lo and hi < m / 2):
            return bits if jump > m / 2 else None
    return None


def counts_to_angle(c: dict, pole_pairs: int, lines, counter_bits, source: str) -> str | None:
    """Replace ``c["encoder_counts"]`` in place by ``c["theta_e"]``
    ([`angle_from_counts`][tuning.identify.log_columns.angle_from_counts], per capture of a burst log);
    returns a note, or None when the log has no count. Refuses a log with both an angle and a count, a count
    without its lines, and a burst log whose counter wraps at a count that is not a whole number of
    revolutions (each capture's angle would then be off by the unknown wraps in the gap before it)."""
    if "encoder_counts" not in c:
        return None
    if "theta_e" in c:
        raise ParameterError(
            f"{source}: has both theta_e and encoder_counts, two angles: keep one (map the other away in the "
            "column map, e.g. --columns theta_e=NAME for the angle only, or drop the theta_e column)."
        )
    if lines is None:
        raise ParameterError(
            f"{source}: encoder_counts needs the encoder's lines per revolution to become an angle: give "
            "--encoder-lines N ([log] encoder_lines = N in the log config) or a --motor drive file with "
            "[sensor] lines."
        )
    if not (isinstance(lines, (int, np.integer)) and not isinstance(lines, bool) and lines > 0):
        raise ParameterError(f"encoder lines must be a positive integer (per revolution), got {lines!r}.")
    if counter_bits is not None and not (
        isinstance(counter_bits, (int, np.integer))
        and not isinstance(counter_bits, bool)
        and counter_bits > 1
    ):
        raise ParameterError(
            f"counter_bits must be the counter's width in bits (e.g. 16 or 32), got {counter_bits!r}."
        )
    counts = np.asarray(c["encoder_counts"], dtype=np.float64)
    bounds = segment_bounds(c["time"]) if "time" in c else np.array([0, counts.size])
    bits = counter_bits if counter_bits is not None else _detected_bits(counts, bounds)
    if bits is not None and bounds.size > 2 and 2**bits % (4 * int(lines)):
        raise ParameterError(
            f"{source}: encoder_counts wrap in a {bits}-bit counter, which is not a whole number of "
            f"revolutions ({4 * int(lines)} counts): in the gaps between the {bounds.size - 1} captures it "
            "wraps an unknown number of times, so their angles disagree: record theta_e, or a count that "
            "wraps once per revolution (the timer's reload at 4 x lines), or one capture."
        )
    del c["encoder_counts"]
    c["theta_e"] = angle_from_counts(counts, int(lines), pole_pairs, bits, bounds)
    wrap = f", unwrapped from a {bits}-bit counter" if bits is not None else ""
    return (
        f"theta_e from encoder_counts ({lines} lines, 4 counts per line{wrap}; zero at the encoder's index)"
    )
