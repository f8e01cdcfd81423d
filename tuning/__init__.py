"""Workflows built on the simulator: gain auto-tuning, parameter identification, Monte Carlo studies.

Data flows one way: ``tuning`` imports ``pmsmjax``, never the reverse. Filled in by the auto-tuning,
identification and Monte Carlo issues.
"""
