"""The stator-frame equation-error fit behind ``identify --sensor-errors`` and the temperature
coefficients: the stator voltage equation integrated over blocks of the log, with the machine, the sensors'
errors and (given a winding-temperature column) ``R(T)`` and ``psi_f(T)`` as unknowns.

``sum u_k dt_k = R_b int i_ab dt + psi_ab(t_end) - psi_ab(t_start)`` over each block ``b``, in the stationary
frame where the held voltage's integral is exact;
``psi_ab = e^{j theta} (L_d i_d + j L_q i_q + psi_f,b)``, ``i_dq = e^{-j theta} i_ab``,
``theta = theta_m - delta``, the true currents ``i_k = (m_k - o_k) / g_k``, and with a temperature column
``R_b = R (1 + alpha (T_b - T_ref))``, ``psi_f,b = psi_f (1 + beta (T_b - T_ref))`` at the block's mean
logged temperature ``T_b`` (without one, ``R_b = R``, ``psi_f,b = psi_f``). With ``dead_time`` the bridge
loses ``V_dt tanh(i_x / eps)`` on each phase ``x`` over each interval (the inverter's error voltage, at
the interval's first sample, as
[`tuning.identify.electrical`][tuning.identify.electrical] models it): ``u_k`` becomes
``u_k - V_dt clarke(tanh(i_abc,k / eps))``; left out, that error lies along the current and biases the
offsets, which are seen through ``R o`` only. The trapezoidal ``int i dt`` is
corrected by its error from the back-EMF's curvature, ``-h^3 omega_e^2 psi_f e^{j theta} / (12 L_d)`` per
interval ``h`` (left in, it lies along the back-EMF and turns the fitted encoder offset by about
``R h^2 omega_e / (12 L)``).

Blocks never span a gap between two captures of a log recorded in bursts
([`tuning.identify.log_columns.segment_bounds`][tuning.identify.log_columns.segment_bounds]): each capture is
cut into its own blocks and the samples after its last whole block are not used.

The start is linear: without sensor errors the flux is ``L_S i_ab + L_D e^{j 2 theta_m} conj(i_ab)
e^{-2 j delta} + psi_f e^{-j delta} e^{j theta_m}`` (``L_S, L_D`` the mean and half-difference of L_d,
L_q), linear in R, ``R alpha``, L_S and the complex coefficients ``L_D e^{-2 j delta}``,
``psi_f e^{-j delta}`` and ``psi_f beta e^{-j delta}``, so ``delta``, psi_f and the coefficients start
from any value. Magnet flux harmonics (``flux_orders``) add their flux to ``psi_ab`` and join the start
and the refinement as ``Re``, ``Im`` of each order's complex amplitude
([`tuning.identify.flux_harmonics_fit`][tuning.identify.flux_harmonics_fit]). The unknowns are then refined
by SciPy's Levenberg-Marquardt
([`tuning.identify.sensor_errors.identify_sensor_errors`][tuning.identify.sensor_errors.identify_sensor_errors]).
"""

import math

import numpy as np

from pmsmjax.spec.validation import ParameterError
from tuning.identify import flux_harmonics_fit as fh

__all__ = ["StatorFrameProblem", "true_currents", "central_jacobian", "noise_level"]

_SQRT3 = math.sqrt(3.0)


def true_currents(m: np.ndarray, offset, gain) -> tuple[np.ndarray, np.ndarray]:
    """``(N, k)`` true phase currents and ``(N,)`` complex alpha-beta current from the ``(N, k)`` readings
    ``m`` of ``k`` sensors (2: phases a, b with ``i_c = -i_a - i_b``; 3: every phase), A."""
    i = (m - offset) / gain
    if i.shape[1] == 2:
        i_ab = i[:, 0] + 1j * (i[:, 0] + 2.0 * i[:, 1]) / _SQRT3
    else:
        i_ab = (2.0 * i[:, 0] - i[:, 1] - i[:, 2]) / 3.0 + 1j * (i[:, 1] - i[:, 2]) / _SQRT3
    return i, i_ab


def central_jacobian(f, x: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """Central-difference Jacobian of ``f`` at ``x`` (unknowns scaled to order one)."""
    cols = []
    for j in range(x.size):
        e = np.zeros_like(x)
        e[j] = h
        cols.append((f(x + e) - f(x - e)) / (2 * h))
    return np.stack(cols, axis=1)


def noise_level(m: np.ndarray) -> float:
    """White-noise level of ``(N, k)`` readings (MAD of second differences), in their unit."""
    d2 = np.diff(m, 2, axis=0)
    mad = np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0)
    return float(np.max(1.4826 * mad / np.sqrt(6.0)))


def _block_edges(bounds: np.ndarray, block: int) -> np.ndarray:
    """``(n_b, 2)`` first and last sample of every block of ``block`` intervals inside a capture."""
    captures = zip(bounds[:-1], bounds[1:], strict=True)
    edges = [(s, s + block) for a, b in captures for s in range(a, b - block, block)]
    return np.asarray(edges, dtype=int).reshape(-1, 2)


class StatorFrameProblem:
    """The block residuals of the module docstring for the unknowns ``p`` (SI; order of ``names``).

    Args:
        log: A [`tuning.identify.sensor_errors.SensorLog`][tuning.identify.sensor_errors.SensorLog].
        block: Log intervals per block.
        reference_c: ``T_ref``, degC: the temperature R and psi_f are fitted at (with a temperature column).
        dead_time: Fit the inverter's error voltage ``V_dt`` (V per phase).
        dead_time_eps_a: The current over which its sign is smoothed, A.
        flux_orders: Orders of magnet flux harmonics to fit (per electrical revolution; not 1, not triplen).

    Raises:
        ParameterError: For a log with fewer than 10 whole blocks.
    """

    def __init__(self, log, block: int, reference_c: float = 20.0, dead_time: bool = False,
                 dead_time_eps_a: float = 0.05, flux_orders=()):  # fmt: skip
        t = log.time
        dt = np.diff(t)
        self.k = log.n_sensors
        self.block = block
        self.edges = _block_edges(log.segments, block)
        self.n_b = self.edges.shape[0]
        if self.n_b < 10:
            raise ParameterError(
                f"{log.source}: {t.size} samples make {self.n_b} blocks of {block} intervals inside its "
                f"captures; record at least {10 * block + 1} samples (in captures of more than {block} rows)."
            )
        self.dt = dt
        u = log.u_ab[:-1, 0] + 1j * log.u_ab[:-1, 1]
        self.U = self._sum(u * dt)
        self.m = log.m
        self.theta_m = log.theta_m
        # Trapezoid error of int i over an interval, -h^3 i'' / 12, from its largest part: the back-EMF turns
        # the current at i'' = omega_e^2 psi_f e^{j theta} / L_d (the rest is smaller by R / (omega_e L)).
        step = np.angle(np.exp(1j * np.diff(self.theta_m)))
        self.curvature = (step / dt) ** 2 * dt**3 / 12.0
        self.theta_mid = self.theta_m[:-1] + 0.5 * step
        self.thermal = log.temperature_c is not None
        self.reference_c = float(reference_c)
        if self.thermal:
            c = np.concatenate([[0.0], np.cumsum(log.temperature_c)])
            a, b = self.edges[:, 0], self.edges[:, 1]
            self.dT = (c[b + 1] - c[a]) / (b + 1 - a) - self.reference_c
        else:
            self.dT = np.zeros(self.n_b)
        self.dead_time = dead_time
        self.eps = dead_time_eps_a
        self.names = ["R", "L_d", "L_q", "psi_f"]
        self.names += ["r_temp_coeff_per_k", "psi_f_temp_coeff_per_k"] if self.thermal else []
        self.names += ["V_dt"] if dead_time else []
        self.flux_orders = tuple(int(k) for k in flux_orders)
        self.names += [f"flux_{k}_{part}" for k in self.flux_orders for part in ("re", "im")]
        #: Unknowns before the sensors' (the machine's, the coefficients, V_dt).
        self.n_machine = len(self.names)
        self.names += [f"o_{p}" for p in "abc"[: self.k]] + [f"g_{p}" for p in "bc"[: self.k - 1]] + ["delta"]
        self.w_kirchhoff = 0.0

    def _sum(self, per_interval: np.ndarray) -> np.ndarray:
        """``(n_b,)`` sums of per-interval values over each block."""
        c = np.concatenate([[0.0], np.cumsum(per_interval)])
        return c[self.edges[:, 1]] - c[self.edges[:, 0]]

    def unpack(self, p) -> dict:
        """``{R, L_d, L_q, psi_f, alpha, beta, V_dt, flux_h, offset (k,), gain (k,), delta}`` from ``p``
        (the coefficients and V_dt zero when not fitted; ``gain[0] = 1``; ``flux_h`` the complex harmonic
        amplitudes, Wb)."""
        k, n = self.k, self.n_machine
        v = dict(zip(self.names[:n], p[:n], strict=True))
        h = np.array([v[f"flux_{o}_re"] + 1j * v[f"flux_{o}_im"] for o in self.flux_orders], complex)
        return {
            "R": v["R"], "L_d": v["L_d"], "L_q": v["L_q"], "psi_f": v["psi_f"],
            "alpha": v.get("r_temp_coeff_per_k", 0.0), "beta": v.get("psi_f_temp_coeff_per_k", 0.0),
            "V_dt": v.get("V_dt", 0.0), "flux_h": h, "offset": p[n : n + k],
            "gain": np.concatenate([[1.0], p[n + k : n + 2 * k - 1]]), "delta": p[-1],
        }  # fmt: skip

    def _dead_time_volt_seconds(self, i: np.ndarray) -> np.ndarray:
        """``(n_b,)`` complex alpha-beta volt-seconds lost per volt of ``V_dt`` over each block."""
        if i.shape[1] == 2:
            i = np.concatenate([i, -i.sum(axis=1, keepdims=True)], axis=1)
        sgn = np.tanh(i[:-1] / self.eps)
        e_ab = (2.0 * sgn[:, 0] - sgn[:, 1] - sgn[:, 2]) / 3.0 + 1j * (sgn[:, 1] - sgn[:, 2]) / _SQRT3
        return self._sum(e_ab * self.dt)

    def voltage_residuals(self, p) -> np.ndarray:
        """``(2 n_b,)`` real and imaginary block residuals, V s."""
        v = self.unpack(p)
        R, L_d, L_q, psi_f, alpha, beta, delta = (
            v[n] for n in ("R", "L_d", "L_q", "psi_f", "alpha", "beta", "delta")
        )
        i, i_ab = true_currents(self.m, v["offset"], v["gain"])
        e = np.exp(1j * (self.theta_m - delta))
        i_dq = i_ab * np.conj(e)
        flux = e * (L_d * i_dq.real + 1j * L_q * i_dq.imag)
        trap = 0.5 * (i_ab[:-1] + i_ab[1:]) * self.dt
        bend = self._sum(self.curvature * np.exp(1j * (self.theta_mid - delta)))
        psi_b = psi_f * (1.0 + beta * self.dT)
        int_i = self._sum(trap) - bend * psi_b / L_d
        a, b = self.edges[:, 0], self.edges[:, 1]
        d_psi = flux[b] - flux[a] + psi_b * (e[b] - e[a])
        if self.flux_orders:
            th = self.theta_m[self.edges] - delta
            psi_h = fh.flux_ab(th, self.flux_orders, v["flux_h"])
            d_psi = d_psi + psi_h[:, 1] - psi_h[:, 0]
        r = self.U - R * (1.0 + alpha * self.dT) * int_i - d_psi
        if self.dead_time:
            r = r - v["V_dt"] * self._dead_time_volt_seconds(i)
        return np.stack([r.real, r.imag], axis=1).ravel()

    def kirchhoff_residuals(self, p) -> np.ndarray:
        """``(N,)`` sums of the three true phase currents (three sensors), A."""
        v = self.unpack(p)
        i, _ = true_currents(self.m, v["offset"], v["gain"])
        return i.sum(axis=1)

    def residuals(self, p, w_v: float = 1.0) -> np.ndarray:
        """Every residual, the voltage ones weighted by ``w_v`` and Kirchhoff's by ``w_kirchhoff``."""
        r = self.voltage_residuals(p) * w_v
        if self.k == 3:
            r = np.concatenate([r, self.w_kirchhoff * self.kirchhoff_residuals(p)])
        return r

    def start(self) -> np.ndarray:
        """The linear start of the module docstring (no current-sensor errors)."""
        i_ab = true_currents(self.m, np.zeros(self.k), np.ones(self.k))[1]
        a, b = self.edges[:, 0], self.edges[:, 1]
        z1 = np.exp(1j * self.theta_m)
        z2 = np.exp(2j * self.theta_m) * np.conj(i_ab)
        d = lambda x: x[b] - x[a]
        trap = self._sum(0.5 * (i_ab[:-1] + i_ab[1:]) * self.dt)
        ri = lambda x: np.concatenate([x.real, x.imag])
        cols = [ri(trap), ri(d(i_ab)), ri(d(z2)), ri(1j * d(z2)), ri(d(z1)), ri(1j * d(z1))]
        if self.thermal:
            cols += [ri(trap * self.dT), ri(d(z1) * self.dT), ri(1j * d(z1) * self.dT)]
        if self.dead_time:
            cols.append(ri(self._dead_time_volt_seconds(self.m)))
        n_h = 2 * len(self.flux_orders)
        cols += [ri(c) for c in fh.start_columns(self.theta_m, self.flux_orders, d)]
        A = np.stack(cols, axis=1)
        scale = np.linalg.norm(A, axis=0)
        scale[scale == 0] = 1.0
        x = np.linalg.lstsq(A / scale, ri(self.U), rcond=None)[0] / scale
        R, L_s, k2, c = x[0], x[1], x[2] + 1j * x[3], x[4] + 1j * x[5]
        delta = -float(np.angle(c))
        L_dlt = float((k2 * np.exp(2j * delta)).real)
        L_d, L_q = L_s + L_dlt, L_s - L_dlt
        floor = max(abs(L_s), 1e-6) * 0.1
        start = [max(R, 1e-3), max(L_d, floor), max(L_q, floor), max(abs(c), 1e-4)]
        if self.thermal:
            start += [x[6] / start[0], float(((x[7] + 1j * x[8]) / c).real)]
        if self.dead_time:
            start.append(x[len(x) - n_h - 1])
        if n_h:
            start += list(fh.rotate_start(x[len(x) - n_h :], self.flux_orders, delta))
        return np.array(start + [0.0] * self.k + [1.0] * (self.k - 1) + [delta])
