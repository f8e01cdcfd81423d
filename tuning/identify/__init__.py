"""Motor parameters (R, L_d, L_q, psi_f, J, B) with error bars from a logged drive run (``pmsmjax identify``).

- [`pipeline`][tuning.identify.pipeline]: [`identify`][tuning.identify.pipeline.identify] and
  [`identify_file`][tuning.identify.pipeline.identify_file], the steps below in order.
- [`log`][tuning.identify.log]: read a log, map its columns and units, turn it into dq, check it.
  Its columns, units and checks are [`log_columns`][tuning.identify.log_columns], shared with the
  observers' stator-frame log [`stator_log`][tuning.identify.stator_log] (``pmsmjax observe``).
- [`electrical`][tuning.identify.electrical], [`mechanical`][tuning.identify.mechanical]: the two residual
  groups (over [`windows`][tuning.identify.windows], in the unknowns of
  [`parameters`][tuning.identify.parameters]).
- [`fit`][tuning.identify.fit]: warm starts and the Levenberg-Marquardt solve.
- [`uncertainty`][tuning.identify.uncertainty]: standard errors, 95 % intervals, identifiability.
- [`plots`][tuning.identify.plots]: measured against fitted signals.
- [`motor_file`][tuning.identify.motor_file]: the identified motor as a drive file (``DIR/motor.toml``).
- [`sensor_errors`][tuning.identify.sensor_errors]: the current sensors' offsets, their gains relative to
  sensor a and the encoder offset from a stator-frame log (``pmsmjax identify --sensor-errors``).
- [`flux_map_fit`][tuning.identify.flux_map_fit], [`flux_map_files`][tuning.identify.flux_map_files]: a
  saturated machine's flux map from a constant-speed log (``pmsmjax identify --flux-map``); its test logs are
  made by [`saturated_reference_log`][tuning.identify.saturated_reference_log].
- [`flux_harmonics_fit`][tuning.identify.flux_harmonics_fit], [`cogging_fit`][tuning.identify.cogging_fit],
  [`ripple_stage`][tuning.identify.ripple_stage]: magnet flux harmonics and cogging torque
  (``--flux-harmonics``, ``--cogging-orders``); [`two_mass_fit`][tuning.identify.two_mass_fit]: a compliant
  shaft (``--two-mass``); their test logs are made by [`heat_run_log`][tuning.identify.heat_run_log] and
  [`shaft_reference_log`][tuning.identify.shaft_reference_log].
- [`excitation`][tuning.identify.excitation]: an experiment that makes every parameter identifiable; simulated
  logs of it (for tests, notebooks and benchmarks) are
  [`pmsmjax.recorded.synthetic_logs.identification_log`][pmsmjax.recorded.synthetic_logs.identification_log].
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
