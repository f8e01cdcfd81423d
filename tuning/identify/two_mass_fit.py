"""The compliant shaft from a run with speed steps (``pmsmjax identify --two-mass``).

**Model** ([`pmsmjax.machines.shaft`][pmsmjax.machines.shaft]): ``J_m dw_m/dt = T_e - B w_m - T_s``,
``J_L dw_L/dt = T_s - T_c``, ``dphi/dt = w_m - w_L``, ``T_s = K phi + D (w_m - w_L)``, with the
electromagnetic torque ``T_e`` of the identified machine from the logged currents
([`tuning.identify.cogging_fit.electromagnetic_torque`][tuning.identify.cogging_fit.electromagnetic_torque])
and a constant load ``T_c``. Only the motor speed is logged.

**Fit.** Output error of the motor speed: the model is linear in its state and its inputs, so over each
interval it is the exact zero-order-hold discretisation (``expm`` of the augmented matrix) with ``T_e``
held at the mean of the interval's two samples, and the speed over the whole log is a linear filter of
``T_e`` (SciPy ``lfilter``). The log is cut into windows (inside each capture); each window's initial state
(``w_m``, the twist and ``w_L``, none of which but the first is measured) is a free linear unknown, projected
out (variable projection), so a torque error does not accumulate from window to window. The unknowns
``log J_m, log J_L, log K, log D, log B`` and ``T_c`` are refined by SciPy's Levenberg-Marquardt from the best
of a grid of stiffnesses (with the rigid inertia from the same projection); the covariance is the sandwich
with Newey-West lags ([`tuning.identify.uncertainty.covariance`][tuning.identify.uncertainty.covariance]).
The resonance ``sqrt(K (J_m + J_L) / (J_m J_L))`` and anti-resonance ``sqrt(K / J_L)`` get their intervals
by the delta method.

**What a log cannot give.** With the currents per ampere as sensor a reads them (``--sensor-errors``), the
torque is ``g_a`` times the true one and so are the inertias, the stiffness, the damping and the friction;
the frequencies are ratios and are not affected. The speed steps must ring the shaft: a log whose torque
has no content near the resonance leaves ``K`` and ``D`` undetermined, and the report says so.
"""

import math

import numpy as np
from scipy import linalg, optimize, signal

from pmsmjax.spec.validation import ParameterError
from tuning.identify.stator_frame_fit import central_jacobian
from tuning.identify.uncertainty import covariance

__all__ = ["TwoMassProblem", "fit_two_mass", "two_mass_from_columns", "REL_TOL"]

#: A parameter is identifiable when its relative standard error is below this.
REL_TOL = 0.05
_NAMES = ("J_m", "J_L", "K", "D", "B")
_UNITS = {"J_m": "kg m^2", "J_L": "kg m^2", "K": "N m/rad", "D": "N m s/rad", "B": "N m s/rad", "T_c": "N m"}


class TwoMassProblem:
    """The projected speed residuals of the module docstring.

    Args:
        time: ``(N,)`` s, uniform within captures. omega_m: ``(N,)`` measured motor speed, rad/s.
        torque: ``(N,)`` electromagnetic torque, N m. segments: ``(S + 1,)`` capture bounds.
        window: Samples per window.
    """

    def __init__(self, time, omega_m, torque, segments, window: int):
        self.h = float(np.median(np.diff(time)))
        self.w = np.asarray(omega_m, float)
        u = np.asarray(torque, float)
        self.u = np.concatenate([0.5 * (u[:-1] + u[1:]), [u[-1]]])
        self.window = window
        starts = [
            s
            for a, b in zip(segments[:-1], segments[1:], strict=True)
            for s in range(a, b - window + 1, window)
        ]
        self.starts = np.asarray(starts, int)
        if self.starts.size < 4:
            raise ParameterError(
                f"--two-mass: the log makes {self.starts.size} windows of {window} samples; record at least "
                f"{4 * window} samples of speed steps."
            )
        self.idx = self.starts[:, None] + np.arange(window)[None, :]
        # Each capture is filtered on its own (the state restarts at a capture's first row).
        self.segments = np.asarray(segments, int)

    def _matrices(self, q):
        j_m, j_l, k, d, b = np.exp(q[:5])
        A = np.array([[-(b + d) / j_m, -k / j_m, d / j_m], [1.0, 0.0, -1.0], [d / j_l, k / j_l, -d / j_l]])
        Bu = np.array([[1.0 / j_m, 0.0], [0.0, 0.0], [0.0, -1.0 / j_l]])
        M = np.zeros((5, 5))
        M[:3, :3], M[:3, 3:] = A * self.h, Bu * self.h
        E = linalg.expm(M)
        return E[:3, :3], E[:3, 3:]

    def residuals(self, q) -> np.ndarray:
        """``(n_windows * window,)`` speed residuals, rad/s, each window's initial state projected out."""
        Ad, Bd = self._matrices(q)
        C = np.array([[1.0, 0.0, 0.0]])
        inputs = self.u
        y = np.zeros_like(self.w)
        for a, b in zip(self.segments[:-1], self.segments[1:], strict=True):
            for col, v in ((0, inputs[a:b]), (1, np.full(b - a, q[5]))):
                num, den = signal.ss2tf(Ad, Bd[:, col : col + 1], C, np.zeros((1, 1)))
                y[a:b] += signal.lfilter(num[0], den, v)
        F = np.zeros((self.window, 3))
        P = np.eye(3)
        for j in range(self.window):
            F[j] = P[0]
            P = Ad @ P
        r = (self.w - y)[self.idx]
        Q, _ = np.linalg.qr(F)
        r = r - (r @ Q) @ Q.T
        return r.ravel()


def _start(pr: TwoMassProblem, j_rigid: float, b: float) -> np.ndarray:
    best = None
    for k in np.geomspace(1e-2, 1e5, 36) * j_rigid / 1e-3:
        for share in (0.25, 0.5, 0.75):
            q = np.array(
                [*np.log([share * j_rigid, (1 - share) * j_rigid, k, 0.05 * math.sqrt(k * j_rigid), b]), 0.0]
            )
            cost = float(np.sum(pr.residuals(q) ** 2))
            if best is None or cost < best[0]:
                best = (cost, q)
    return best[1]


def _rigid(time, omega_m, torque, segments) -> tuple[float, float]:
    """``(J, B)`` of a rigid shaft by equation error over 10 ms steps (a start for the fit)."""
    rows, rhs = [], []
    n = max(2, round(0.01 / float(np.median(np.diff(time)))))
    for a, b in zip(segments[:-1], segments[1:], strict=True):
        for s in range(a, b - n, n):
            dt = time[s + n] - time[s]
            rows.append([omega_m[s + n] - omega_m[s], np.mean(omega_m[s : s + n + 1]) * dt, dt])
            rhs.append(np.mean(torque[s : s + n + 1]) * dt)
    x = np.linalg.lstsq(np.asarray(rows), np.asarray(rhs), rcond=None)[0]
    return max(float(x[0]), 1e-9), max(float(x[1]), 1e-3 * float(x[0]))


def _entry(value, stderr, unit, ok):
    finite = math.isfinite(stderr)
    ok = bool(ok and finite)
    return {"value": float(value), "stderr": float(stderr) if finite else None,
            "ci95": [float(value - 1.96 * stderr), float(value + 1.96 * stderr)] if ok else [None, None],
            "unit": unit, "identifiable": ok}  # fmt: skip


def fit_two_mass(time, omega_m, torque, segments=None, window_s: float = 0.05, source: str = "log") -> dict:
    """Fit the two-mass mechanics (module docstring).

    Args:
        time: ``(N,)`` s. omega_m: ``(N,)`` measured motor speed, rad/s. torque: ``(N,)`` the machine's
            electromagnetic torque, N m. segments: ``(S + 1,)`` capture bounds (default: one capture).
        window_s: Window length, s.
        source: A name for messages.

    Returns:
        The ``two_mass`` entry of ``params.json``: ``J_m``, ``J_L``, ``K``, ``D``, ``B``, ``T_c``,
        ``resonance_hz``, ``anti_resonance_hz`` (value, stderr, 95 % interval, identifiable),
        ``residual_rms_rad_s`` and the method.
    """
    time = np.asarray(time, float)
    segments = np.array([0, time.size]) if segments is None else np.asarray(segments, int)
    if float(np.ptp(omega_m)) <= 0.0:
        raise ParameterError(
            f"{source}: --two-mass needs a run with speed steps; the logged speed is constant."
        )
    h = float(np.median(np.diff(time)))
    pr = TwoMassProblem(time, omega_m, torque, segments, max(10, round(window_s / h)))
    j_rigid, b_rigid = _rigid(time, omega_m, torque, segments)
    q0 = _start(pr, j_rigid, b_rigid)
    scale = np.ones(6)
    scale[5] = max(1e-3, 0.01 * float(np.sqrt(np.mean(np.asarray(torque) ** 2))))
    fun = lambda x: pr.residuals(x * scale)
    sol = optimize.least_squares(fun, q0 / scale, method="lm", xtol=1e-12, ftol=1e-12, gtol=1e-12)
    q = sol.x * scale
    J = central_jacobian(fun, sol.x, 1e-6) / scale
    r = pr.residuals(q)
    lags = max(1, pr.window // 10)
    cov = covariance([(J, r, (1, r.size), lags)])[0]
    se = np.sqrt(np.abs(np.diag(cov)))
    values = np.exp(q[:5])
    out = {}
    for j, name in enumerate(_NAMES):
        out[name] = _entry(values[j], values[j] * se[j], _UNITS[name], se[j] < REL_TOL)
    torque_rms = float(np.sqrt(np.mean(np.asarray(torque) ** 2)))
    out["T_c"] = _entry(q[5], se[5], "N m", se[5] < REL_TOL * max(torque_rms, 1e-9))

    def log_freq(qq, anti=False):
        j_m, j_l, k = np.exp(qq[:3])
        return 0.5 * (math.log(k) - math.log(j_l)) if anti else 0.5 * math.log(k * (j_m + j_l) / (j_m * j_l))

    for key, anti in (("resonance_hz", False), ("anti_resonance_hz", True)):
        g = np.array([(log_freq(q + e, anti) - log_freq(q - e, anti)) / 2e-6 for e in np.eye(6) * 1e-6])
        s = math.sqrt(max(float(g @ cov @ g), 0.0))
        f = math.exp(log_freq(q, anti)) / (2.0 * math.pi)
        out[key] = _entry(f, f * s, "Hz", s < REL_TOL)
    out["residual_rms_rad_s"] = float(np.sqrt(np.mean(r**2)))
    out["windows"] = int(pr.starts.size)
    out["method"] = (
        "output error of the motor speed through the two-mass model driven by the identified machine's "
        f"torque from the logged currents; {pr.window}-sample windows, their initial states projected out; "
        "Levenberg-Marquardt (SciPy) in log parameters; sandwich covariance with Newey-West lags; 95 % "
        "intervals = 1.96 standard errors"
    )
    out["solver"] = {"converged": bool(sol.success), "evaluations": int(sol.nfev)}
    return out


def two_mass_from_columns(
    cols: dict, machine: dict, harmonics: dict | None, pole_pairs: int, reference_c: float, segments,
    source: str = "log",
) -> dict:  # fmt: skip
    """``fit_two_mass`` on the stator-frame stage's corrected columns: the torque of the identified
    ``machine`` ([`SensorErrors.machine`][tuning.identify.sensor_errors.SensorErrors]) plus the identified
    cogging of ``harmonics`` (``params.json``'s entry, or None)."""
    from tuning.identify.cogging_fit import electromagnetic_torque

    if "omega_m" not in cols:
        raise ParameterError(
            f"{source}: --two-mass needs the motor speed omega_m: log it, or drop --two-mass."
        )
    torque = electromagnetic_torque(cols, machine, pole_pairs, reference_c)
    for row in (harmonics or {}).get("cogging", {}).get("rows", []):
        n, c, phi = row["order"], row["amplitude"]["value"], row["phase_rad"]["value"]
        torque = torque + c * np.sin(n * cols["theta_e"] + phi)
    return fit_two_mass(cols["time"], cols["omega_m"], torque, segments, source=source)
