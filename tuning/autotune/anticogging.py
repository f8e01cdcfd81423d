"""Learning an anticogging table by gradients through the closed loop.

The FOC's [`AnticoggingTable`][pmsmjax.controllers.anticogging.AnticoggingTable] (a q current over one
electrical revolution, ``N`` bins) is fitted so that the drive holds a low speed (30 r/min by default) with
the least speed ripple, over a batch of runs that start at angles spread over the revolution, so that their
measurement windows cover every bin. The speed error ``w_m - w_m*`` at every period of every window is the
residual vector of a nonlinear least-squares problem in the ``N`` table values, solved by optimistix's
Levenberg-Marquardt with the Jacobian by forward-mode differentiation through the simulation (``N``
directions). The problem is nearly linear in the table (the feed-forward current enters the torque linearly;
only the flux harmonics' torque ``1.5 p i_q . eps`` and the loop's clipping are not), so a few steps
converge.

ODrive's firmware calibrates its table by stepping the position setpoint slowly through the encoder counts
and storing the velocity integrator's current at each (``Firmware/MotorControl/controller.cpp``): a direct
measurement of the torque
needed at each angle, which requires a stiff position loop and many revolutions. The fit here needs neither:
it sees the speed loop's response to the table and chooses the table that cancels what is left, the loop's
lag at the cogging frequency included.

Figures of merit (r/min): the RMS and the peak-to-peak of the speed error over the windows (after each
run's settling time), before and after.
"""

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from pmsmjax.assemble import with_parts
from pmsmjax.controllers.anticogging import AnticoggingTable
from pmsmjax.controllers.foc import FOC
from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.simulate import simulate
from pmsmjax.spec.validation import ParameterError
from pmsmjax.units import rad_s_to_rpm, rpm_to_rad_s

#: The least-squares solvers ``method`` chooses from.
SOLVERS = {"gauss_newton": optx.GaussNewton, "levenberg_marquardt": optx.LevenbergMarquardt}

__all__ = [
    "AnticoggingRuns",
    "AnticoggingResult",
    "ripple_runs",
    "speed_errors",
    "ripple",
    "learn_anticogging",
]


@dataclasses.dataclass(frozen=True)
class AnticoggingRuns:
    """The batch the table is fitted on: ``n_runs`` runs at ``speed_rpm`` (r/min) without load, each
    started at speed from the electrical angle ``start_angles[k]`` (rad), ``settle_s`` (s) of settling and
    ``window_s`` (s) measured."""

    speed_rpm: float
    start_angles: np.ndarray
    settle_s: float
    window_s: float

    def scenario(self) -> Scenario:
        """The runs' scenario: constant speed reference, no load."""
        return Scenario(
            duration_s=self.settle_s + self.window_s,
            speed_ref=Profile.constant(rpm_to_rad_s(self.speed_rpm)),
            load_torque=Profile.constant(0.0),
        )


def ripple_runs(drive, speed_rpm: float = 30.0, n_runs: int = 6, settle_s: float = 0.3, window_s=None):
    """Runs whose windows cover one electrical revolution: ``n_runs`` start angles ``2 pi k / n_runs``, each
    window (default) ``1.25 / n_runs`` of an electrical revolution at ``speed_rpm`` (r/min), so the windows
    overlap by a quarter of their length; durations rounded to whole control periods."""
    p = drive.machine.motor.pole_pairs
    omega_e = p * rpm_to_rad_s(speed_rpm)
    if window_s is None:
        window_s = 1.25 * 2.0 * np.pi / omega_e / n_runs
    whole = lambda t: round(t / drive.Ts) * drive.Ts
    angles = 2.0 * np.pi * np.arange(n_runs) / n_runs
    return AnticoggingRuns(speed_rpm, angles, whole(settle_s), whole(window_s))


def speed_errors(drive, runs: AnticoggingRuns):
    """``(n_runs, W)`` speed error ``w_m - w_m*`` (rad/s) over each run's window, ``W`` periods."""
    scenario = runs.scenario()
    speed = rpm_to_rad_s(runs.speed_rpm)
    skip = round(runs.settle_s / drive.Ts)

    def one(theta0):
        trace = simulate(drive, scenario, initial_state=drive.init(speed, theta0))
        return trace.omega_m[skip:] - trace.speed_ref[skip:]

    return jax.vmap(one)(jnp.asarray(runs.start_angles, drive.machine.motor.R.dtype))


def ripple(errors) -> dict:
    """``{"rms_rpm", "peak_to_peak_rpm"}`` of speed errors (rad/s): RMS over all windows, and the largest
    peak-to-peak of one window, r/min."""
    e = np.asarray(errors, float)
    return {
        "rms_rpm": float(rad_s_to_rpm(np.sqrt(np.mean(e**2)))),
        "peak_to_peak_rpm": float(rad_s_to_rpm(np.max(np.ptp(e, axis=-1)))),
    }


@dataclasses.dataclass(frozen=True)
class AnticoggingResult:
    """What [`learn_anticogging`][tuning.autotune.anticogging.learn_anticogging] found.

    Attributes:
        table: The learnt table.
        drive: The drive with the table in its controller.
        before: Ripple without a table ([`ripple`][tuning.autotune.anticogging.ripple]), r/min.
        after: Ripple with the learnt table, r/min.
        steps: Levenberg-Marquardt steps taken.
        runs: The batch it was fitted on.
    """

    table: AnticoggingTable
    drive: object
    before: dict
    after: dict
    steps: int
    runs: AnticoggingRuns

    @property
    def rms_cut(self) -> float:
        """RMS speed ripple without the table over with it."""
        return self.before["rms_rpm"] / self.after["rms_rpm"]

    @property
    def peak_to_peak_cut(self) -> float:
        """Peak-to-peak speed ripple without the table over with it."""
        return self.before["peak_to_peak_rpm"] / self.after["peak_to_peak_rpm"]


def learn_anticogging(
    drive,
    *,
    n_bins: int = 128,
    speed_rpm: float = 30.0,
    n_runs: int = 6,
    settle_s: float = 0.3,
    window_s: float | None = None,
    max_steps: int = 6,
    rtol: float = 1e-3,
    atol: float = 1e-6,
    method: str = "gauss_newton",
) -> AnticoggingResult:
    """Fit ``drive``'s anticogging table (module docstring).

    Args:
        drive: A drive with a three-phase [`FOC`][pmsmjax.controllers.foc.FOC] in speed mode.
        n_bins: Bins over one electrical revolution.
        speed_rpm: The low speed the ripple is minimised at, r/min.
        n_runs: Runs, started at angles spread over the revolution.
        settle_s: Settling time before each window, s.
        window_s: Each run's window, s (default: [`ripple_runs`][tuning.autotune.anticogging.ripple_runs]).
        max_steps: Levenberg-Marquardt steps at most.
        rtol: Relative tolerance on the table's change between steps.
        atol: Absolute tolerance on it, A.
        method: ``"gauss_newton"`` (the problem is nearly linear: one step does most of the work) or
            ``"levenberg_marquardt"`` (damped, slower).

    Returns:
        The [`AnticoggingResult`][tuning.autotune.anticogging.AnticoggingResult].

    Raises:
        ParameterError: For a controller that is not a FOC cascade in speed mode.
    """
    c = drive.controller
    if not isinstance(c, FOC) or c.mode != "speed":
        raise ParameterError(
            f"anticogging needs a three-phase FOC cascade in speed mode; this drive has "
            f"{type(c).__name__}{'' if not isinstance(c, FOC) else ' in ' + c.mode + ' mode'}: use --control "
            "pi (or smc) in speed mode."
        )
    runs = ripple_runs(drive, speed_rpm, n_runs, settle_s, window_s)
    dtype = drive.machine.motor.R.dtype

    def with_table(iq):
        # zero mean: cogging has none, and a constant q current is the speed loop's integrator's to give
        # (a direction the ripple barely sees, which would leave the problem ill-conditioned)
        return with_parts(drive, {"controller.anticogging": AnticoggingTable(iq - jnp.mean(iq))})

    @eqx.filter_jit
    def residuals(iq, args):
        del args
        return speed_errors(with_table(iq), runs).reshape(-1)

    y0 = jnp.zeros(n_bins, dtype)
    before = ripple(speed_errors(with_table(y0), runs))
    solver = SOLVERS[method](rtol=rtol, atol=atol)
    solution = optx.least_squares(residuals, solver, y0, max_steps=max_steps, throw=False)
    table = AnticoggingTable(solution.value - jnp.mean(solution.value))
    learnt = with_parts(drive, {"controller.anticogging": table})
    after = ripple(speed_errors(learnt, runs))
    steps = int(solution.stats["num_steps"])
    return AnticoggingResult(table, learnt, before, after, steps, runs)
