"""pmsmjax: a differentiable, batched simulator of permanent-magnet synchronous motor drives in JAX.

Quick start::

    import pmsmjax
    drive = pmsmjax.presets.book_drive()
    scenario = pmsmjax.presets.book_scenario()
    trace = pmsmjax.simulate(drive, scenario)

The names below are imported on first use (PEP 562), not when the package is: ``import pmsmjax.cli``
(the ``pmsmjax`` command) then loads neither JAX nor Equinox, so ``pmsmjax --help`` and every refusal of
bad input answer in a fraction of a second. ``pmsmjax.X`` and ``from pmsmjax import X`` work as before.
"""

import sys
import types

from pmsmjax._lazy import lazy_exports
from pmsmjax.xla_cpu import request_small_loop_kernels

__version__ = "0.1.0"

# Before anything compiles: loops of tiny bodies as one kernel each (pmsmjax/xla_cpu.py says why).
request_small_loop_kernels()

#: Public name -> (module, attribute or None for the module itself).
_LAZY = {
    "analysis": ("analysis", None),
    "controllers": ("controllers", None),
    "estimators": ("estimators", None),
    "frames": ("frames", None),
    "inverters": ("inverters", None),
    "io": ("io", None),
    "machines": ("machines", None),
    "plotting": ("plotting", None),
    "presets": ("presets", None),
    "scenarios": ("scenarios", None),
    "jobs": ("jobs", None),
    "recorded": ("recorded", None),
    "spec": ("spec", None),
    # Short names for modules that live in the folders above.
    "logs": ("io.logs", None),
    "metrics": ("analysis.metrics", None),
    "multiphase_frames": ("frames.multiphase", None),
    "presets_six_phase": ("presets.six_phase", None),
    "presets_five_phase": ("presets.five_phase", None),
    "replay": ("recorded.replay", None),
    "Drive": ("drive", "Drive"),
    "DriveState": ("drive", "DriveState"),
    "PeriodInputs": ("drive", "PeriodInputs"),
    "Profile": ("scenarios", "Profile"),
    "Scenario": ("scenarios", "Scenario"),
    "stack_scenarios": ("scenarios", "stack_scenarios"),
    "simulate": ("simulate", "simulate"),
    "Trace": ("trace", "Trace"),
    "ParameterError": ("spec.validation", "ParameterError"),
}

__all__ = sorted(_LAZY)


__getattr__, __dir__ = lazy_exports(__name__, _LAZY)


class _Package(types.ModuleType):
    """The package module: importing the submodule ``pmsmjax.simulate`` (which the import system binds
    as an attribute of its package) must not hide the function ``pmsmjax.simulate``."""

    def __setattr__(self, name, value):
        if name == "simulate" and isinstance(value, types.ModuleType):
            value = value.simulate
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package
