"""Gradient auto-tuning of a drive's gains over a batch of scenarios (``pmsmjax tune``).

- [`scenario_batches`][tuning.autotune.scenario_batches]: seeded train and held-out batches of speed and load
  steps.
- [`objectives`][tuning.autotune.objectives]: per-scenario metrics and the batch cost (ITAE plus penalties).
- [`tuner`][tuning.autotune.tuner]: [`tune`][tuning.autotune.tuner.tune], Adam or BFGS on the log-gains,
  checkpointed, resumable.
- [`quasi_newton`][tuning.autotune.quasi_newton]: the step-capped BFGS behind ``method="bfgs"``.
- [`baselines`][tuning.autotune.baselines]: derivative-free searches (Nelder-Mead, CMA-ES) on the same cost.
- [`job`][tuning.autotune.job]: the ``pmsmjax tune`` job (tune, check on the held-out batch, write files).
- [`drive_batches`][tuning.autotune.drive_batches], [`drive_scaling`][tuning.autotune.drive_scaling]: the
  job's batches, observer settings and penalty weights from the user's drive file.

The gains themselves (names, ``log(p/p0)`` parameterisation, gains files) are
[`tuning.parameters`][tuning.parameters].
"""

from tuning.autotune.baselines import BaselineResult, cma_available, cma_es, design_rule_cost, nelder_mead
from tuning.autotune.job import DEFAULT_CONFIG, read_tune_toml, run_tune_job
from tuning.autotune.objectives import ObjectiveWeights, batch_cost, batch_metrics
from tuning.autotune.scenario_batches import ScenarioBatch, make_batch
from tuning.autotune.tuner import TuneConfig, TuneResult, tune

__all__ = [
    "TuneConfig",
    "TuneResult",
    "tune",
    "ObjectiveWeights",
    "batch_cost",
    "batch_metrics",
    "ScenarioBatch",
    "make_batch",
    "BaselineResult",
    "design_rule_cost",
    "nelder_mead",
    "cma_es",
    "cma_available",
    "DEFAULT_CONFIG",
    "read_tune_toml",
    "run_tune_job",
]
