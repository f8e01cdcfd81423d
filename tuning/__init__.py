"""Workflows built on the simulator, one subpackage each.

- [`tuning.autotune`][tuning.autotune]: gradient auto-tuning of the drive's gains (``pmsmjax tune``).
- [`tuning.identify`][tuning.identify]: motor parameters with error bars from a logged run
  (``pmsmjax identify``).
- [`tuning.montecarlo`][tuning.montecarlo]: robustness studies over parameter tolerances
  (``pmsmjax montecarlo``).
- [`tuning.parameters`][tuning.parameters]: a drive's gains by name, their log-parameterisation and gains
  files, shared by auto-tuning (which writes ``gains.toml``) and Monte Carlo studies (which read it and vary
  leaves).

Data flows one way: ``tuning`` imports ``pmsmjax``, never the reverse.
"""
