"""Motor parameters (R, L_d, L_q, psi_f, J, B) with error bars from a logged drive run (``pmsmjax identify``).

- :mod:`~tuning.identify.pipeline`: :func:`identify` and :func:`identify_file`, the steps below in order.
- :mod:`~tuning.identify.log`: read a log, map its columns and units, turn it into dq, check it.
  Its columns, units and checks are :mod:`~tuning.identify.log_columns`, shared with the
  observers' stator-frame log :mod:`~tuning.identify.stator_log` (``pmsmjax observe``).
- :mod:`~tuning.identify.electrical`, :mod:`~tuning.identify.mechanical`: the two residual groups
  (over :mod:`~tuning.identify.windows`, in the unknowns of :mod:`~tuning.identify.parameters`).
- :mod:`~tuning.identify.fit`: warm starts and the Levenberg-Marquardt solve.
- :mod:`~tuning.identify.uncertainty`: standard errors, 95 % intervals, identifiability.
- :mod:`~tuning.identify.plots`: measured against fitted signals.
- :mod:`~tuning.identify.motor_file`: the identified motor as a drive file (``DIR/motor.toml``).
- :mod:`~tuning.identify.flux_map_fit`, :mod:`~tuning.identify.flux_map_files`: a saturated machine's
  flux map from a constant-speed log (``pmsmjax identify --flux-map``); its test logs are made by
  :mod:`~tuning.identify.saturated_reference_log`.
- :mod:`~tuning.identify.excitation`: an experiment that makes every parameter identifiable; simulated
  logs of it (for tests, notebooks and benchmarks) are
  :func:`pmsmjax.recorded.synthetic_logs.identification_log`.
"""

from tuning.identify.excitation import identification_scenario, prbs
from tuning.identify.log import DriveLog, drive_log_from_columns, load_drive_log, read_log_config
from tuning.identify.pipeline import NAMES, UNITS, IdentifyOptions, IdentifyResult, identify, identify_file

__all__ = [
    "IdentifyOptions",
    "IdentifyResult",
    "identify",
    "identify_file",
    "NAMES",
    "UNITS",
    "DriveLog",
    "load_drive_log",
    "drive_log_from_columns",
    "read_log_config",
    "identification_scenario",
    "prbs",
]
