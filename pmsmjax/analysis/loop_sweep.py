"""A loop's response measured on the nonlinear simulation: a sine injected at its break point, correlated.

The independent check of the linearisation
([`pmsmjax.analysis.loop_linearisation`][pmsmjax.analysis.loop_linearisation]): the drive starts at the steady
state, a sinusoid ``w_k = a sin(2 pi f k Ts)`` (held over each period) is added at the loop's break point
through the scenario's perturbation profiles (``measured_iq_perturbation`` for the current loop,
``iq_ref_perturbation`` for the speed loop), and after a settling time the signal after the injection
``v`` and
the loop's return ``y = v - w`` are correlated with ``exp(-j 2 pi f k Ts)`` over a window of a whole number of
periods of ``f`` (the frequencies are snapped to that window's bins). ``L = -Y / V``: the loop transfer the
way a network analyser or MATLAB's frequency-response estimation measures it at an opened loop. The current
loop is measured with the speed loop open (the controller in current mode, ``i_q*`` held at its steady value),
as it is linearised. One batch of scenarios, one per frequency, through ``jax.vmap``.
"""

import jax
import numpy as np

from pmsmjax.analysis.loop_linearisation import LOOPS, current_mode, linearise, operating_state
from pmsmjax.drive import Drive
from pmsmjax.scenarios import Profile, Scenario, stack_scenarios
from pmsmjax.simulate import simulate
from pmsmjax.spec.validation import ParameterError, check_choice, check_positive

__all__ = ["sweep_loop", "snap_frequencies"]


def snap_frequencies(freq_hz, window_periods: int, Ts: float) -> np.ndarray:
    """The frequencies (Hz) moved to the nearest whole number of cycles in ``window_periods`` periods of
    ``Ts`` (s), at least one cycle, below Nyquist; duplicates removed."""
    cycles = np.clip(np.round(np.asarray(freq_hz, float) * window_periods * Ts), 1, window_periods // 2 - 1)
    return np.unique(cycles) / (window_periods * Ts)


def sweep_loop(
    drive: Drive,
    loop: str,
    speed_m: float,
    load_nm: float,
    freq_hz,
    amplitude_a: float,
    settle_s: float = 0.2,
    window_s: float = 0.1,
) -> tuple[np.ndarray, np.ndarray]:
    """The measured loop transfer ``L`` of ``loop`` at the operating point (module docstring).

    Args:
        drive: The drive (the scope of
            [`check_linearisable`][pmsmjax.analysis.loop_linearisation.check_linearisable]).
        loop: ``"current"`` or ``"speed"``.
        speed_m: Speed reference, mechanical rad/s.
        load_nm: Load torque, N m.
        freq_hz: Test frequencies, Hz (snapped to the window's bins).
        amplitude_a: Amplitude of the injected sine, A (small: a few % of the operating current).
        settle_s: Time given to the start of the sine's transient before the window, s.
        window_s: Correlation window, s (a whole number of periods; sets the frequency resolution).

    Returns:
        ``(frequencies (K,) Hz, L (K,) complex)``.

    Raises:
        ParameterError: For a loop name, a non-positive amplitude or time, or a drive outside the
            linearisation's scope.
    """
    check_choice("loop", loop, LOOPS)
    check_positive("amplitude_a", amplitude_a, "A")
    check_positive("settle_s", settle_s, "s")
    check_positive("window_s", window_s, "s")
    lin = linearise(drive, speed_m, load_nm)
    start = operating_state(drive, lin)
    Ts = drive.Ts
    n_settle, n_window = int(round(settle_s / Ts)), int(round(window_s / Ts))
    if n_window < 8:
        raise ParameterError(f"window_s = {window_s} s is under 8 control periods: give a longer window.")
    freqs = snap_frequencies(freq_hz, n_window, Ts)
    n = n_settle + n_window
    k = np.arange(n)
    plant = drive if loop == "speed" else current_mode(drive)
    iq_star = float(np.asarray(start.controller.iq_ref))
    field = "iq_ref_perturbation" if loop == "speed" else "measured_iq_perturbation"
    rows = []
    for f in freqs:
        w = amplitude_a * np.sin(2.0 * np.pi * f * k * Ts)
        rows.append(
            Scenario(
                n * Ts,
                speed_ref=Profile.constant(speed_m),
                load_torque=Profile.constant(load_nm),
                iq_ref=Profile.constant(iq_star),
                **{field: Profile(k * Ts, w, np.zeros(n))},
            )
        )
    batch = stack_scenarios(rows)
    traces = jax.vmap(lambda s: simulate(plant, s, initial_state=start))(batch)
    w = amplitude_a * np.sin(2.0 * np.pi * freqs[:, None] * k[None, :] * Ts)
    if loop == "speed":
        v = np.asarray(traces.i_dq_ref[:, :, 1])
        y = v - w
    else:
        y = np.asarray(traces.i_dq[:, :, 1])
        v = y + w
    keep = slice(n_settle, n)
    phasor = np.exp(-2j * np.pi * freqs[:, None] * k[None, keep] * Ts)
    Y = np.sum((y[:, keep] - y[:, keep].mean(axis=1, keepdims=True)) * phasor, axis=1)
    V = np.sum((v[:, keep] - v[:, keep].mean(axis=1, keepdims=True)) * phasor, axis=1)
    return freqs, -Y / V
