"""``pmsmjax replay``: the machine run under a log's recorded voltages
([`pmsmjax.recorded.replay`][pmsmjax.recorded.replay]), returned for the command line to write."""

import dataclasses
import os
from collections.abc import Mapping

import numpy as np

from pmsmjax.io.csv_dialect import CsvDialect
from pmsmjax.recorded.replay import DEFAULT_HOLD, replay_log


@dataclasses.dataclass(frozen=True)
class ReplaySpec:
    """What to replay: `log` a ``.csv``/``.npz``/``.mat`` log, `motor` a preset name or drive file, `hold`
    ``"auto"``, ``"rotor"`` or ``"stator"``, `n_substeps` RK4 steps per row (None: automatic),
    `time_unit` of the log's time column (``"s"``, ``"ms"``, ``"us"``), `check_units` refuse implausible
    units, `columns` the column map, `units` the units map, `dialect` a CSV file's stated dialect (see
    [`pmsmjax.recorded.replay.replay_log`][pmsmjax.recorded.replay.replay_log])."""

    log: str | os.PathLike
    motor: str | os.PathLike
    hold: str = DEFAULT_HOLD
    n_substeps: int | None = None
    time_unit: str = "s"
    check_units: bool = True
    columns: Mapping[str, str] | None = None
    units: Mapping[str, str] | None = None
    dialect: CsvDialect | None = None


@dataclasses.dataclass(frozen=True)
class ReplayResult:
    """`columns`: ``(N,)`` float64 arrays ``time`` (s), ``i_d``, ``i_q`` (A), ``omega_m`` (mechanical
    rad/s), ``theta_e`` (electrical rad), in the order of ``replay.csv``; `notes`: the console's lines
    (the hold chosen, the log's columns not used)."""

    columns: Mapping[str, np.ndarray]
    notes: tuple[str, ...]


def run_replay(spec: ReplaySpec) -> ReplayResult:
    """Replay the log of `spec` through its motor; nothing is written."""
    notes: list[str] = []
    columns = replay_log(
        spec.log,
        spec.motor,
        hold=spec.hold,
        n_substeps=spec.n_substeps,
        time_unit=spec.time_unit,
        check_units=spec.check_units,
        report=notes,
        columns=spec.columns,
        units=spec.units,
        dialect=spec.dialect,
    )
    return ReplayResult(columns, tuple(notes))
