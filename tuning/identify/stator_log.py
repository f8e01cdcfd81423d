"""A drive log for an observer (``pmsmjax observe``): read any stator-frame layout, convert to alpha-beta
and SI units, check it.

The columns, their units and the column map are those of
[`tuning.identify.log_columns`][tuning.identify.log_columns]. An observer estimates the rotor angle, so its
log gives the stationary-frame signals: voltages ``u_alpha, u_beta`` | ``u_a, u_b, u_c`` | duties
``d_a, d_b, d_c`` with ``U_dc``, currents ``i_alpha, i_beta`` | ``i_a, i_b, i_c``; ``theta_e`` and ``omega_m``
are read only as the truth the estimate is scored against. The checks are the identification log's
([`tuning.identify.log`][tuning.identify.log]), a dq log refused with the reason.
"""

import dataclasses
import difflib
import os

import jax
import numpy as np

from pmsmjax.io.csv_dialect import CsvDialect
from pmsmjax.io.log_units import merge_units
from pmsmjax.io.logs import check_columns, column_names
from pmsmjax.spec.validation import ParameterError
from tuning.identify.log_columns import (
    CURRENT_SETS,
    MAX_STEP_S,
    VOLTAGE_SETS,
    apply_units,
    check_grid,
    check_speed_against_angle,
    pick_set,
    read_canonical,
    to_dq64,
)

__all__ = ["StatorLog", "TRUTH", "load_stator_log", "stator_log_from_columns"]

#: Signal sets an observer can use: it estimates the angle, so it needs stator-frame signals.
_STATOR_VOLTAGE_SETS = {k: v for k, v in VOLTAGE_SETS.items() if k != "dq"}
_STATOR_CURRENT_SETS = {k: v for k, v in CURRENT_SETS.items() if k != "dq"}
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
    dialect: CsvDialect | None = None,
) -> StatorLog:
    """Read a ``.csv``/``.npz``/``.mat`` log for an observer and return a checked
    [`StatorLog`][tuning.identify.stator_log.StatorLog].

    Voltages ``u_alpha, u_beta`` | ``u_a, u_b, u_c`` | duties ``d_a, d_b, d_c`` with ``U_dc`` (or `u_dc`,
    V); currents ``i_alpha, i_beta`` | ``i_a, i_b, i_c``; other columns are ignored unless named in
    `truth` (a subset of ``theta_e``, ``omega_m``). `columns`, `units`, `resample`: as
    [`load_drive_log`][tuning.identify.log.load_drive_log]; `pole_pairs` (when both truth columns are given)
    checks the speed against the angle (and converts a speed in erpm); `dialect`: a CSV file's stated
    delimiter, decimal mark and header row. Units in the column names (``Time [ms]``) add to `units`.
    """
    bad = [c for c in truth if c not in TRUTH]
    if bad:
        hints = [f"{b!r} -> {difflib.get_close_matches(b, TRUTH, 1, 0.5) or 'no close name'}" for b in bad]
        raise ParameterError(
            f"truth columns: unknown {bad} ({'; '.join(hints)}); the truth an observer is scored against is "
            f"theta_e (electrical rad) and/or omega_m (mechanical rad/s); map the file's names with a column "
            "map (e.g. theta_e=angle)."
        )
    named: dict = {}
    present = read_canonical(path, columns, dialect=dialect, named_units=named)
    units = merge_units(named, dict(units or {}), f"log {path}")
    unmapped = sorted(set(column_names(path, dialect)) - set(present) - set((columns or {}).values()))
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
    """A checked [`StatorLog`][tuning.identify.stator_log.StatorLog] from canonical columns (NumPy arrays);
    see [`load_stator_log`][tuning.identify.stator_log.load_stator_log]. `other_columns`: the file's other
    column names, searched for close matches of missing ones."""
    if not any(n in cols for n in sum(_STATOR_VOLTAGE_SETS.values(), ())) and all(
        n in cols for n in VOLTAGE_SETS["dq"]
    ):
        raise ParameterError(
            f"{source}: the voltages are logged in dq (u_d, u_q), which needs the rotor angle that the "
            "observer is to estimate: log the stator-frame voltages (u_alpha,u_beta or u_a,u_b,u_c or duties "
            "d_a,d_b,d_c)."
        )
    if not any(n in cols for n in sum(_STATOR_CURRENT_SETS.values(), ())) and all(
        n in cols for n in CURRENT_SETS["dq"]
    ):
        raise ParameterError(
            f"{source}: the currents are logged in dq (i_d, i_q), which needs the rotor angle that the "
            "observer is to estimate: log the stator-frame currents (i_alpha,i_beta or i_a,i_b,i_c)."
        )
    try:
        vset = pick_set(cols, _STATOR_VOLTAGE_SETS, "voltage", source)
        iset = pick_set(cols, _STATOR_CURRENT_SETS, "current", source)
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
    apply_units(c, units or {}, source, pole_pairs)
    notes = []
    c, dt, resampled = check_grid(c, np.diff(c["time"]), resample, source)
    if resampled:
        notes.append(resampled)
    Ts = float(np.median(dt))
    if Ts > MAX_STEP_S * (1.0 + 1e-9):  # a 1 ms step of a ms count, to rounding
        raise ParameterError(
            f"{source}: sampling step {Ts:.3g} s is longer than {MAX_STEP_S:g} s; an observer needs the "
            "control-period samples (1 kHz or faster). If time is not in seconds, set its unit "
            "(--units time=ms or time=us)."
        )
    if "theta_e" in truth and "omega_m" in truth and pole_pairs is not None:
        check_speed_against_angle(c, pole_pairs, source)
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
    return to_dq64(c, names, frame, np.zeros_like(c["time"]), u_dc)
