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

from pmsmjax._lazy import by_module, lazy_exports
from pmsmjax.xla_cpu import request_small_loop_kernels

__version__ = "0.1.0"

# Before anything compiles: loops of tiny bodies as one kernel each (pmsmjax/xla_cpu.py says why).
request_small_loop_kernels()

#: The subpackages and modules re-exported under their own names.
_MODULES = (
    "analysis", "controllers", "estimators", "frames", "inverters", "io", "machines", "plotting", "presets",
    "scenarios", "jobs", "recorded", "spec",
)  # fmt: skip
#: Public name -> (module, attribute or None for the module itself).
_LAZY = {
    **{name: (name, None) for name in _MODULES},
    # Short names for modules that live in the folders above.
    "logs": ("io.logs", None),
    "metrics": ("analysis.metrics", None),
    "multiphase_frames": ("frames.multiphase", None),
    "presets_six_phase": ("presets.six_phase", None),
    "presets_five_phase": ("presets.five_phase", None),
    "replay": ("recorded.replay", None),
    **by_module(
        {
            "drive": ("Drive", "DriveState", "PeriodInputs"),
            "scenarios": ("Profile", "Scenario", "stack_scenarios"),
            "simulate": ("simulate",),
            "trace": ("Trace",),
            "spec.validation": ("ParameterError",),
        }
    ),
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
