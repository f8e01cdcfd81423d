"""Harmonic spectra and total harmonic distortion over a window of whole fundamental periods.

A signal observed over a window ``T_w`` holding ``K`` whole fundamental periods has the Fourier series
``x(t) = sum_n Re(X_n e^{j 2 pi n t / T_w})``; component ``n`` lies at ``n / T_w`` Hz, the fundamental at
``n = K``. Amplitudes are peak values (``|X_n|``, the DC term ``|X_0|`` is the mean).

Two ways to get the coefficients, one per kind of signal:

- [`piecewise_constant_spectrum`][pmsmjax.analysis.spectra.piecewise_constant_spectrum]: exact coefficients of
  a piecewise-constant signal (an inverter's phase or line voltage), the integrals of ``e^{-j w t}`` over each
  constant interval. No sampling, no aliasing: every switching edge is placed exactly.
- [`sampled_spectrum`][pmsmjax.analysis.spectra.sampled_spectrum]: FFT of uniform samples covering the window
  (a phase current, which is continuous and whose harmonics fall off as ``1/(n w L)`` of the voltage's, so a
  few tens of samples per PWM period leave aliasing far below the components that matter).

[`thd`][pmsmjax.analysis.spectra.thd]: ``THD = sqrt(sum_{n != 0, K; f_n <= f_max} |X_n|^2) / |X_K|``, i.e.
every component of the window's Fourier series other than DC and the fundamental, up to ``f_max``. With PWM,
the distortion sits in carrier groups around multiples of the switching frequency, far above the 40th-50th
harmonic of the power-quality standards, so ``f_max`` must be stated with every figure; pmsmjax's comparisons
use ``f_max = 4 f_sw`` (the first four carrier groups and their sidebands).
"""

import numpy as np

__all__ = ["Spectrum", "piecewise_constant_spectrum", "sampled_spectrum", "thd"]


class Spectrum:
    """Peak amplitudes at ``frequencies_hz`` (``n / window_s``); the fundamental is component ``cycles``.

    Args:
        amplitudes: ``(n_max + 1, ...)`` peak amplitudes, in the signal's unit.
        window_s: Length of the analysed window, s.
        cycles: Number of whole fundamental periods in the window.
    """

    def __init__(self, amplitudes: np.ndarray, window_s: float, cycles: int):
        self.amplitudes = np.asarray(amplitudes)
        self.window_s = float(window_s)
        self.cycles = int(cycles)

    @property
    def frequencies_hz(self) -> np.ndarray:
        """``(n_max + 1,)`` frequency of each component, Hz: ``n / window_s``."""
        return np.arange(self.amplitudes.shape[0]) / self.window_s

    @property
    def fundamental(self) -> np.ndarray:
        """Peak amplitude of the fundamental (same unit as the signal)."""
        return self.amplitudes[self.cycles]

    def harmonic_orders(self) -> np.ndarray:
        """Frequency of every component in multiples of the fundamental (fractional between harmonics)."""
        return np.arange(self.amplitudes.shape[0]) / self.cycles


def _check_window(window_s, cycles):
    if not window_s > 0:
        raise ValueError(f"window_s must be > 0, got {window_s}.")
    if not isinstance(cycles, (int, np.integer)) or cycles < 1:
        raise ValueError(
            f"cycles (whole fundamental periods in the window) must be an int >= 1, got {cycles}."
        )


def piecewise_constant_spectrum(times, values, cycles: int, n_max: int) -> Spectrum:
    """Exact Fourier amplitudes of a piecewise-constant signal.

    ``X_n = (2/T_w) sum_k v_k int_{t_k}^{t_{k+1}} e^{-j w_n t} dt`` for ``n >= 1`` (``1/T_w`` for DC).

    Args:
        times: ``(K+1,)`` non-decreasing interval bounds, s (the window is ``times[0]`` to ``times[-1]``).
        values: ``(K, ...)`` value held in each interval.
        cycles: Whole fundamental periods in the window.
        n_max: Highest component computed.

    Returns:
        The [`Spectrum`][pmsmjax.analysis.spectra.Spectrum].
    """
    times = np.asarray(times, float)
    values = np.asarray(values, float)
    window = times[-1] - times[0]
    _check_window(window, cycles)
    t = times - times[0]
    n = np.arange(1, n_max + 1)
    w = 2.0 * np.pi * n / window
    amplitudes = np.empty((n_max + 1,) + values.shape[1:])
    flat = values.reshape(values.shape[0], -1)
    amplitudes[0] = np.abs((np.diff(t) @ flat) / window).reshape(values.shape[1:])
    # int e^{-jwt} over [t_k, t_k+1] = (e^{-jw t_k} - e^{-jw t_k+1}) / (jw), computed in chunks of orders.
    for lo in range(0, n_max, 256):
        wc = w[lo : lo + 256, None]
        e = np.exp(-1j * wc * t[None, :])
        integrals = (e[:, :-1] - e[:, 1:]) / (1j * wc)
        amplitudes[1 + lo : 1 + lo + wc.shape[0]] = np.abs(2.0 / window * integrals @ flat).reshape(
            (wc.shape[0],) + values.shape[1:]
        )
    return Spectrum(amplitudes, window, cycles)


def sampled_spectrum(samples, window_s: float, cycles: int, n_max: int | None = None) -> Spectrum:
    """Fourier amplitudes from uniform samples spanning exactly the window.

    Args:
        samples: ``(N, ...)`` samples, spacing ``window_s / N``.
        window_s: Length of the window, s.
        cycles: Whole fundamental periods in the window.
        n_max: Highest component (default and at most ``N // 2 - 1``, below Nyquist).

    Returns:
        The [`Spectrum`][pmsmjax.analysis.spectra.Spectrum].
    """
    x = np.asarray(samples, float)
    _check_window(window_s, cycles)
    N = x.shape[0]
    top = N // 2 - 1
    n_max = top if n_max is None else n_max
    if n_max > top:
        raise ValueError(f"n_max = {n_max} is at or above Nyquist for {N} samples: use at most {top}.")
    X = np.fft.rfft(x, axis=0)[: n_max + 1] / N
    amplitudes = 2.0 * np.abs(X)
    amplitudes[0] *= 0.5
    return Spectrum(amplitudes, window_s, cycles)


def thd(spectrum: Spectrum, f_max_hz: float) -> np.ndarray:
    """Total harmonic distortion of every component but DC and the fundamental up to ``f_max_hz``.

    Args:
        spectrum: The spectrum.
        f_max_hz: Highest frequency counted, Hz.

    Returns:
        The THD as a ratio (not %).

    Raises:
        ValueError: When the spectrum does not reach ``f_max_hz``.
    """
    f = spectrum.frequencies_hz
    if f[-1] + 0.5 / spectrum.window_s < f_max_hz:
        raise ValueError(f"the spectrum stops at {f[-1]:g} Hz, below f_max = {f_max_hz:g} Hz.")
    keep = (f <= f_max_hz * (1 + 1e-12)) & (np.arange(f.size) != 0) & (np.arange(f.size) != spectrum.cycles)
    a = spectrum.amplitudes
    return np.sqrt(np.sum(a[keep] ** 2, axis=0)) / a[spectrum.cycles]
