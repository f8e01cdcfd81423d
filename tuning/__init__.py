"""Workflows built on the simulator, one subpackage each.

- :mod:`tuning.autotune`: gradient auto-tuning of the drive's gains (``pmsmjax tune``).
- :mod:`tuning.identify`: motor parameters with error bars from a logged run (``pmsmjax identify``).
- :mod:`tuning.montecarlo`: robustness studies over parameter tolerances (``pmsmjax montecarlo``).
- :mod:`tuning.parameters`: a drive's gains by name, their log-parameterisation and gains files, shared
  by auto-tuning (which writes ``gains.toml``) and Monte Carlo studies (which read it and vary leaves).

Data flows one way: ``tuning`` imports ``pmsmjax``, never the reverse.
"""
