"""The tune job's scenario batches on a drive file: which batch maker, with which ranges, for a control
or an observer ([`tuning.autotune.drive_scaling`][tuning.autotune.drive_scaling] has the scaling rules).

- controls: [`tuning.autotune.scenario_batches.make_batch`][tuning.autotune.scenario_batches.make_batch] over
  the drive file's ``[tuning]`` speed, load and duration ranges at its control period;
- chapter 5 observers:
  [`tuning.autotune.observers.make_observer_batch`][tuning.autotune.observers.make_observer_batch], speeds up
  to the scaled top speed (down to 5 % of it, starts from 25 %), loads up to the rated torque, warm-up and
  hold scaled with the tuning durations, durations half the drive's tuning durations;
- chapter 6 estimators:
  [`tuning.autotune.hfi_tuning.make_injection_batch`][tuning.autotune.hfi_tuning.make_injection_batch] on
  [`injection_spec`][tuning.autotune.hfi_tuning.injection_spec] likewise, loads up to
  [`injection_load_nm`][tuning.autotune.hfi_tuning.injection_load_nm] (on a flux map the injection region's
  torque where it is below the rated one).

On the book drive every batch is the book's to the bit (tests/tuning/test_drive_scaling.py).
"""

import dataclasses
from collections.abc import Callable

from pmsmjax.spec.drive_spec import DriveSpec
from tuning.autotune import drive_scaling
from tuning.autotune.observers import HOLD_S, RATED_SPEED_RPM, make_observer_batch, observer_tuning
from tuning.autotune.scenario_batches import WARMUP_S, make_batch

__all__ = ["DriveBatches", "drive_batches"]


@dataclasses.dataclass(frozen=True)
class DriveBatches:
    """`make(n, seed, *, duration_s, kinds, plant_spread)`: a batch of the drive; `duration_s`: the default
    duration range, s; `ranges`: the drive-scaled keywords given to the maker (for result.json);
    `warmup_s`: the observers' sensored warm-up, s (None for a control)."""

    make: Callable
    duration_s: tuple[float, float]
    ranges: dict
    warmup_s: float | None = None


def drive_batches(spec: DriveSpec, estimator: str | None = None) -> DriveBatches:
    """The batches of the tune job on ``spec`` for a control (``estimator`` None) or observer
    ``estimator`` (module docstring)."""
    if estimator is None:
        options = drive_scaling.control_batch_options(spec)
        duration = options.pop("duration_s")
        return DriveBatches(_bound(make_batch, options), duration, options)
    stretch = drive_scaling.time_scale(spec)
    warmup = WARMUP_S * stretch
    options = dict(warmup_s=warmup, hold_s=HOLD_S * stretch, Ts=spec.Ts)
    duration = tuple(0.5 * d for d in spec.tuning["duration_s"])
    if observer_tuning(estimator).chapter6:
        from tuning.autotune.hfi_tuning import injection_batch_maker, injection_load_nm

        maker = injection_batch_maker(estimator, spec)
        options.update(load_nm=injection_load_nm(estimator, spec))
    else:
        maker = make_observer_batch
        top = drive_scaling.observer_top_speed_rpm(spec, RATED_SPEED_RPM)
        options.update(
            speed_rpm=(0.05 * top, top),
            start_rpm=(0.25 * top, top),
            load_nm=(0.0, spec.ratings["rated_torque_nm"]),
        )
    return DriveBatches(_bound(maker, options), duration, options, warmup)


def _bound(maker, options: dict):
    def make(n, seed, **more):
        return maker(n, seed, **options, **more)

    return make
