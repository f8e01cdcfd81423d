"""Monte Carlo robustness studies of a drive over parameter tolerances (``pmsmjax montecarlo``).

- [`study`][tuning.montecarlo.study]: what a study varies ([`Study`][tuning.montecarlo.study.Study], its TOML
  file, applying a sample).
- [`distributions`][tuning.montecarlo.distributions]: tolerances as distributions, seeded (Latin hypercube)
  sampling.
- [`kernel`][tuning.montecarlo.kernel]: one closed-loop run reduced to its metrics while it runs.
- [`runner`][tuning.montecarlo.runner]: [`run_study`][tuning.montecarlo.runner.run_study], chunked, sharded
  over every device, resumable.
- [`summary`][tuning.montecarlo.summary], [`figures`][tuning.montecarlo.figures]: percentiles, failure rates,
  CVaR, sensitivities; histograms, fan charts, a tornado chart.
- [`cpu_devices`][tuning.montecarlo.cpu_devices]: [`split_cpu`][tuning.montecarlo.cpu_devices.split_cpu], one
  JAX device per CPU core, and [`set_up_devices`][tuning.montecarlo.cpu_devices.set_up_devices], a study's
  devices (a core each, or a cluster's hosts).

[`split_cpu`][tuning.montecarlo.cpu_devices.split_cpu] only works before JAX initialises its backends, and
importing this package runs the imports below: none of them may touch a device at import time (no module-level
arrays).
"""

from tuning.montecarlo.chunk_files import load_results
from tuning.montecarlo.cpu_devices import split_cpu
from tuning.montecarlo.distributions import Distribution, sample
from tuning.montecarlo.runner import VOLATILE_KEYS, StudyRunner, chunk_layout, run_study
from tuning.montecarlo.study import Study
from tuning.montecarlo.study_file import read_study_toml

__all__ = [
    "Study",
    "read_study_toml",
    "run_study",
    "load_results",
    "StudyRunner",
    "chunk_layout",
    "VOLATILE_KEYS",
    "Distribution",
    "sample",
    "split_cpu",
]
