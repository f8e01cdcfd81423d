"""Current-sensor offsets, the gain ratio between the sensors and the encoder's angle offset from a
stator-frame log (``pmsmjax identify --sensor-errors``).

The sensors are those of [`pmsmjax.estimators.current_sensors`][pmsmjax.estimators.current_sensors] and
[`pmsmjax.estimators.position_sensors.Encoder`][pmsmjax.estimators.position_sensors.Encoder]: sensor ``k``
reads ``m_k = g_k i_k + o_k`` (two sensors on phases a and b, ``i_c = -i_a - i_b``; or three) and the angle
is read as ``theta_m = theta_e + delta``. The log gives what the controller saw: the phase currents
``i_a, i_b (, i_c)`` as read, the measured ``theta_e`` (that is ``theta_m``) and the commanded stator-frame
voltages (``u_alpha, u_beta`` | ``u_a, u_b, u_c`` | duties with ``U_dc``), each held from its row to the next
(a real inverter).

**What the errors look like.** An offset is a stationary vector: in the rotor frame a ripple at the
electrical frequency whose alpha-beta vector is the offset; a gain mismatch distorts the current circle into
an ellipse, a ripple at twice the electrical frequency; an encoder offset turns the measured frame, so the
back-EMF, which lies on the rotor's q axis, shows up on the measured d axis as ``-omega_e psi_f sin(delta)``.

**Formulation.** One nonlinear least-squares fit of the stator voltage equation
``u_ab = R i_ab + d psi_ab / dt`` integrated over blocks of ``block`` log intervals, in the stationary frame
where the held voltage's integral is exact (``sum u_k dt_k``):

``sum u_k dt_k = R int i_ab dt + psi_ab(t_end) - psi_ab(t_start)``,
``psi_ab = e^{j theta} (L_d i_d + j L_q i_q + psi_f)``, ``i_dq = e^{-j theta} i_ab``,
``theta = theta_m - delta``, and the true currents ``i_k = (m_k - o_k) / g_k``. The trapezoidal ``int i dt``
is corrected by its error from the back-EMF's curvature, ``-h^3 omega_e^2 psi_f e^{j theta} / (12 L_d)`` per
interval ``h``: left in, it lies along the back-EMF and turns the fitted encoder offset by about
``R h^2 omega_e / (12 L)`` (1e-4 rad at 10 kHz and 480 rad/s, two standard errors of a 0.4 s log).

The unknowns are R, L_d, L_q, psi_f, the offsets, the gains relative to sensor a and ``delta``: the encoder
offset is fitted jointly with the machine instead of read off a zero crossing of the back-EMF (the usual
encoder-offset calibration at standstill locks the rotor with a d-axis current, as ODrive's
``ENCODER_OFFSET_CALIBRATION`` and TI's SPRABZ0 do; with the back-EMF it is the angle of the no-load
voltage against the counted angle). At speed the fit separates ``delta`` from the ``L_q i_q`` cross term
because the log's currents vary (steps of i_d and i_q, two speeds). With three sensors the sampled
currents must also sum to zero (Kirchhoff), which adds a residual per sample and pins the offsets' common
part, which the amplitude-invariant Clarke transform drops.

The start is linear: without sensor errors the flux is ``L_S i_ab + L_D e^{j 2 theta_m} conj(i_ab) e^{-2 j
delta} + psi_f e^{-j delta} e^{j theta_m}`` (``L_S, L_D`` the mean and half-difference of L_d, L_q), linear in
R, L_S and the complex coefficients ``L_D e^{-2 j delta}`` and ``psi_f e^{-j delta}``, so ``delta`` and psi_f
start from any offset. The fit is SciPy's Levenberg-Marquardt; the covariance is the identification's
sandwich with Newey-West lags
([`tuning.identify.uncertainty.covariance`][tuning.identify.uncertainty.covariance]) and 95 % intervals are
1.96 standard errors.

**What a log cannot give.** The absolute current gain: scaling every current by ``g`` is explained by R,
L_d, L_q divided by ``g`` (psi_f and the encoder offset do not move), so the gains are reported relative to
sensor a (its gain is 1) and R, L_d, L_q are per ampere as sensor a reads it; a reference current (a
calibrated probe) is needed for the absolute gain. The offsets are seen through the resistive drop
``R o`` (and the saliency): an uncorrected inverter voltage error (dead time) of the same order biases
them, so the voltages must be the ones the bridge applied.
"""

import dataclasses
import math

import jax
import numpy as np
from scipy import optimize

from pmsmjax.io.logs import check_columns
from pmsmjax.spec.validation import ParameterError
from tuning.identify.log_columns import VOLTAGE_SETS, apply_units, check_grid, pick_set, to_dq64
from tuning.identify.uncertainty import covariance

__all__ = [
    "SensorLog",
    "SensorErrors",
    "sensor_log_from_columns",
    "identify_sensor_errors",
    "corrected_columns",
    "IDENTIFIABLE_STDERR",
]

#: A sensor error is reported identifiable when its standard error is below this (offsets in A, the gain
#: ratio relative, the encoder offset in electrical rad).
IDENTIFIABLE_STDERR = {"current_offset_a": 0.005, "current_gain": 0.002, "encoder_offset_rad": 0.005}
#: The stator-frame voltage sets a sensor-error fit can use (the voltage in dq needs the true angle).
_STATOR_VOLTAGE_SETS = {k: v for k, v in VOLTAGE_SETS.items() if k != "dq"}
_SQRT3 = math.sqrt(3.0)
_NOTE_GAIN = (
    "the absolute current gain is not identifiable from a log: scaling every current by g is explained by "
    "R, L_d and L_q divided by g; the gains are relative to sensor a (gain 1) and R, L_d, L_q are per ampere "
    "as sensor a reads it; a calibrated reference current gives the absolute gain"
)


@dataclasses.dataclass(frozen=True)
class SensorLog:
    """A stator-frame log with the phase currents as the sensors read them (``N`` rows, SI units).

    Attributes:
        time: ``(N,)`` sample times, s.
        u_ab: ``(N, 2)`` alpha-beta voltage held from row k to k+1, V.
        m: ``(N, k)`` phase currents as read by the ``k`` sensors (phases a, b (, c)), A.
        theta_m: ``(N,)`` measured electrical angle, rad.
        source: A name for messages.
    """

    time: np.ndarray
    u_ab: np.ndarray
    m: np.ndarray
    theta_m: np.ndarray
    source: str = "log"

    @property
    def n_sensors(self) -> int:
        """Number of current sensors (2: phases a, b; 3: every phase)."""
        return self.m.shape[1]


@dataclasses.dataclass
class SensorErrors:
    """The fitted sensor errors.

    Attributes:
        offset_a: ``(k,)`` offset of each sensor, A.
        gain: ``(k,)`` gain of each sensor relative to sensor a (``gain[0] = 1``).
        encoder_offset_rad: The measured angle minus the rotor's, electrical rad.
        machine: ``{R, L_d, L_q, psi_f}`` of the same fit (ohm, H, H, Wb; R and L per sensor-a ampere).
        summary: The JSON-able report (``params.json``'s ``sensor_errors``).
    """

    offset_a: np.ndarray
    gain: np.ndarray
    encoder_offset_rad: float
    machine: dict
    summary: dict


def sensor_log_from_columns(
    cols: dict, *, units: dict | None = None, u_dc: float | None = None, resample: bool = False,
    source: str = "log",
) -> tuple[SensorLog, dict]:  # fmt: skip
    """Check canonical columns for a sensor-error fit.

    Args:
        cols: Canonical columns ([`tuning.identify.log_columns`][tuning.identify.log_columns]): ``time``,
            one stator-frame voltage set, ``i_a, i_b`` (and ``i_c``: a third sensor unless it is
            ``-i_a - i_b`` to rounding, the firmware's reconstruction), ``theta_e`` (the measured angle);
            ``omega_m``, ``T_L``, ``U_dc`` are kept when present.
        units: ``{column or group: unit}`` as for the identification log.
        u_dc: DC-link voltage, V, for duties without a ``U_dc`` column.
        resample: Resample an irregular time grid instead of refusing it.
        source: A name for messages.

    Returns:
        ``(SensorLog, columns)``: the log, and the columns used, in SI units (for
        [`corrected_columns`][tuning.identify.sensor_errors.corrected_columns]).

    Raises:
        ParameterError: For a log without phase currents, the measured angle or stator-frame voltages.
    """
    lack = [n for n in ("i_a", "i_b", "theta_e") if n not in cols]
    if lack:
        raise ParameterError(
            f"{source}: sensor errors need the phase currents as the sensors read them (i_a, i_b, and i_c "
            f"with a third sensor) and the measured angle theta_e; missing {', '.join(lack)}: log them (or "
            "map their names with a column map), or drop --sensor-errors."
        )
    try:
        vset = pick_set(cols, _STATOR_VOLTAGE_SETS, "voltage", source)
    except ParameterError as err:
        raise ParameterError(f"{err} Sensor errors need the stator-frame voltages.") from None
    need = ["time", *_STATOR_VOLTAGE_SETS[vset], "i_a", "i_b", "theta_e"]
    if vset == "duty" and u_dc is None:
        need.append("U_dc")
    optional = [n for n in ("i_c", "omega_m", "T_L", "U_dc") if n not in need]
    c = check_columns(cols, need, optional, source=source)
    apply_units(c, units or {}, source)
    c, _, _ = check_grid(c, np.diff(c["time"]), resample, source)
    with jax.enable_x64(True):
        u_ab = to_dq64(c, _STATOR_VOLTAGE_SETS[vset], vset, np.zeros_like(c["time"]), u_dc)
    phases = [c["i_a"], c["i_b"]]
    if "i_c" in c:
        total = c["i_a"] + c["i_b"] + c["i_c"]
        scale = max(float(np.max(np.abs(c["i_a"]))), 1e-12)
        if np.max(np.abs(total)) > 1e-9 * scale:
            phases.append(c["i_c"])
    log = SensorLog(c["time"], np.asarray(u_ab), np.stack(phases, axis=1), c["theta_e"], source)
    return log, c


def _true_currents(m, offset, gain):
    """``(N, k)`` true phase currents and ``(N,)`` complex alpha-beta current from the readings."""
    i = (m - offset) / gain
    if i.shape[1] == 2:
        i_ab = i[:, 0] + 1j * (i[:, 0] + 2.0 * i[:, 1]) / _SQRT3
    else:
        i_ab = (2.0 * i[:, 0] - i[:, 1] - i[:, 2]) / 3.0 + 1j * (i[:, 1] - i[:, 2]) / _SQRT3
    return i, i_ab


class _Problem:
    """The block residuals of the module docstring for the unknowns ``x`` (scaled)."""

    def __init__(self, log: SensorLog, block: int):
        t = log.time
        dt = np.diff(t)
        self.k = log.n_sensors
        self.n_b = (t.size - 1) // block
        if self.n_b < 10:
            raise ParameterError(
                f"{log.source}: {t.size} samples make {self.n_b} blocks of {block} intervals; record at "
                f"least {10 * block + 1} samples."
            )
        end = self.n_b * block
        self.block = block
        self.dt = dt[:end]
        u = log.u_ab[:end, 0] + 1j * log.u_ab[:end, 1]
        self.U = (u * self.dt).reshape(self.n_b, block).sum(axis=1)
        self.m = log.m[: end + 1]
        self.theta_m = log.theta_m[: end + 1]
        self.edges = np.arange(0, end + 1, block)
        # Trapezoid error of int i over an interval, -h^3 i'' / 12, from its largest part: the back-EMF turns
        # the current at i'' = omega_e^2 psi_f e^{j theta} / L_d (the rest is smaller by R / (omega_e L)).
        step = np.angle(np.exp(1j * np.diff(self.theta_m)))
        self.curvature = (step / self.dt) ** 2 * self.dt**3 / 12.0
        self.theta_mid = self.theta_m[:-1] + 0.5 * step
        self.names = ["R", "L_d", "L_q", "psi_f"] + [f"o_{p}" for p in "abc"[: self.k]]
        self.names += [f"g_{p}" for p in "bc"[: self.k - 1]] + ["delta"]
        self.w_kirchhoff = 0.0

    def unpack(self, p):
        k = self.k
        return p[0], p[1], p[2], p[3], p[4 : 4 + k], np.concatenate([[1.0], p[4 + k : 3 + 2 * k]]), p[-1]

    def voltage_residuals(self, p):
        R, L_d, L_q, psi_f, offset, gain, delta = self.unpack(p)
        _, i_ab = _true_currents(self.m, offset, gain)
        e = np.exp(1j * (self.theta_m - delta))
        i_dq = i_ab * np.conj(e)
        psi = e * (L_d * i_dq.real + psi_f + 1j * L_q * i_dq.imag)
        trap = 0.5 * (i_ab[:-1] + i_ab[1:]) * self.dt
        trap = trap - self.curvature * psi_f / L_d * np.exp(1j * (self.theta_mid - delta))
        int_i = trap.reshape(self.n_b, self.block).sum(axis=1)
        r = self.U - R * int_i - (psi[self.edges[1:]] - psi[self.edges[:-1]])
        return np.stack([r.real, r.imag], axis=1).ravel()

    def kirchhoff_residuals(self, p):
        _, _, _, _, offset, gain, _ = self.unpack(p)
        i, _ = _true_currents(self.m, offset, gain)
        return i.sum(axis=1)

    def residuals(self, p, w_v=1.0):
        r = self.voltage_residuals(p) * w_v
        if self.k == 3:
            r = np.concatenate([r, self.w_kirchhoff * self.kirchhoff_residuals(p)])
        return r

    def start(self) -> np.ndarray:
        """The linear start of the module docstring (no current-sensor errors)."""
        i_ab = _true_currents(self.m, np.zeros(self.k), np.ones(self.k))[1]
        a, b = self.edges[:-1], self.edges[1:]
        z1 = np.exp(1j * self.theta_m)
        z2 = np.exp(2j * self.theta_m) * np.conj(i_ab)
        d = lambda x: x[b] - x[a]
        trap = (0.5 * (i_ab[:-1] + i_ab[1:]) * self.dt).reshape(self.n_b, self.block).sum(axis=1)
        ri = lambda x: np.concatenate([x.real, x.imag])
        cols = [ri(trap), ri(d(i_ab)), ri(d(z2)), ri(1j * d(z2)), ri(d(z1)), ri(1j * d(z1))]
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
        return np.array(start + [0.0] * self.k + [1.0] * (self.k - 1) + [delta])


def identify_sensor_errors(log: SensorLog, block: int = 50) -> SensorErrors:
    """Fit the current-sensor offsets, their relative gains and the encoder offset (module docstring).

    Args:
        log: The stator-frame log
            ([`sensor_log_from_columns`][tuning.identify.sensor_errors.sensor_log_from_columns]).
        block: Log intervals per integration block.

    Returns:
        The [`SensorErrors`][tuning.identify.sensor_errors.SensorErrors], with intervals in its summary.

    Raises:
        ParameterError: For a log too short for the blocks, or a fit that fails numerically.
    """
    pr = _Problem(log, block)
    p0 = pr.start()
    i_rms = float(np.sqrt(np.mean(log.m**2)))
    scale = np.abs(p0)
    scale[4 : 4 + pr.k] = max(0.01 * i_rms, 1e-3)
    scale[4 + pr.k :] = 1.0  # gains and the angle: order one
    sigma_i = _noise_level(log.m)
    if pr.k == 3:
        pr.w_kirchhoff = 1.0 / max(_SQRT3 * sigma_i, 1e-9)  # three readings' noise in each sum
    w_v = 1.0
    x = p0 / scale
    for _ in range(3):
        fun = lambda x, w=w_v: pr.residuals(x * scale, w)
        sol = optimize.least_squares(fun, x, method="lm", xtol=1e-12, ftol=1e-12, gtol=1e-12)
        x = sol.x
        rv = pr.voltage_residuals(x * scale)
        new_w = 1.0 / max(float(np.sqrt(np.mean(rv**2))), 1e-300)
        moved = abs(new_w / w_v - 1.0)
        w_v = new_w
        if pr.k == 2 or moved < 0.02:
            break
    p = x * scale
    J = _jacobian(lambda x: pr.residuals(x * scale, w_v), x) / scale  # per unit of each parameter
    r = pr.residuals(p, w_v)
    groups = [(J[: 2 * pr.n_b], r[: 2 * pr.n_b], (1, pr.n_b), 3)]
    if pr.k == 3:
        n_k = r.size - 2 * pr.n_b
        groups.append((J[2 * pr.n_b :], r[2 * pr.n_b :], (1, n_k), 1))
    if not np.all(np.isfinite(p)):
        raise ParameterError(f"{log.source}: the sensor-error fit failed numerically (non-finite values).")
    cov = covariance(groups)[0]
    se = np.sqrt(np.abs(np.diag(cov)))
    return _result(pr, p, se, sol, w_v, log)


def _jacobian(f, x, h=1e-6):
    """Central-difference Jacobian of ``f`` at ``x`` (unknowns scaled to order one)."""
    cols = []
    for j in range(x.size):
        e = np.zeros_like(x)
        e[j] = h
        cols.append((f(x + e) - f(x - e)) / (2 * h))
    return np.stack(cols, axis=1)


def _noise_level(m: np.ndarray) -> float:
    """White-noise level of the current readings, A (MAD of second differences, as the fit's weights)."""
    d2 = np.diff(m, 2, axis=0)
    mad = np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0)
    return float(np.max(1.4826 * mad / np.sqrt(6.0)))


def _entry(value, stderr, unit, limit):
    finite = math.isfinite(stderr)
    ok = finite and stderr < limit
    return {
        "value": float(value),
        "stderr": float(stderr) if finite else None,
        "ci95": [float(value - 1.96 * stderr), float(value + 1.96 * stderr)] if ok else [None, None],
        "unit": unit,
        "identifiable": bool(ok),
    }


def _result(pr: _Problem, p, se, sol, w_v, log) -> SensorErrors:
    R, L_d, L_q, psi_f, offset, gain, delta = pr.unpack(p)
    delta = float(math.remainder(delta, 2 * math.pi))
    k = pr.k
    lim = IDENTIFIABLE_STDERR
    offsets = [
        _entry(offset[j], se[4 + j], "A", lim["current_offset_a"]) | {"sensor": "abc"[j]} for j in range(k)
    ]
    gains = [{"value": 1.0, "stderr": 0.0, "ci95": [1.0, 1.0], "unit": "", "identifiable": None,
              "sensor": "a", "note": "the reference: the gains are relative to sensor a"}]  # fmt: skip
    gains += [
        _entry(gain[j], se[3 + k + j], "", lim["current_gain"] * gain[j]) | {"sensor": "abc"[j]}
        for j in range(1, k)
    ]
    enc = _entry(delta, se[-1], "rad", lim["encoder_offset_rad"])
    enc["value_deg"] = math.degrees(delta)
    turns = float(np.sum(np.abs(np.angle(np.exp(1j * np.diff(pr.theta_m)))))) / (2 * math.pi)
    if turns < 1.0:
        # Without back-EMF only the saliency sees the angle, and it cannot tell d from -d (180 deg apart).
        enc.update(identifiable=False, ci95=[None, None])
        enc["note"] = (
            f"not determined by this log: the rotor turns {turns:.2g} electrical revolutions (at least "
            "one is needed: the back-EMF gives the encoder offset; the saliency alone leaves it 180 deg "
            "ambiguous)"
        )
    rv = pr.voltage_residuals(p)
    summary = {
        "sensors": k,
        "current_offset_a": offsets,
        "current_gain": gains,
        "encoder_offset_rad": enc,
        "not_identifiable": {"absolute_current_gain": _NOTE_GAIN},
        "machine_of_this_fit": {
            "R": float(R),
            "L_d": float(L_d),
            "L_q": float(L_q),
            "psi_f": float(psi_f),
            "note": "R, L_d, L_q per ampere as sensor a reads it",
        },  # fmt: skip
        "residual_rms_vs": float(np.sqrt(np.mean(rv**2))),
        "method": "equation error of the stator-frame voltage equation integrated over blocks of "
        f"{pr.block} intervals (flux-linkage form), the measured angle turned by the encoder offset and "
        "the currents corrected by the sensors' offsets and gains; Levenberg-Marquardt (SciPy), sandwich "
        "covariance with Newey-West lags, 95 % intervals = 1.96 standard errors",
        "solver": {"converged": bool(sol.success), "evaluations": int(sol.nfev)},
        "log": {"source": log.source, "samples": int(log.time.size)},
    }
    machine = {"R": float(R), "L_d": float(L_d), "L_q": float(L_q), "psi_f": float(psi_f)}
    return SensorErrors(np.asarray(offset, float), np.asarray(gain, float), delta, machine, summary)


def corrected_columns(cols: dict, errors: SensorErrors) -> dict:
    """The columns with the identified errors taken out: true phase currents (relative to sensor a's
    gain) and the rotor angle; an error the log does not determine is left in.

    Args:
        cols: The SI columns that
            [`sensor_log_from_columns`][tuning.identify.sensor_errors.sensor_log_from_columns] returned.
        errors: The fit.

    Returns:
        The columns for
        [`tuning.identify.log.drive_log_from_columns`][tuning.identify.log.drive_log_from_columns]: the
        voltages, ``time``, ``omega_m``, ``T_L``, ``U_dc`` as given, ``i_a, i_b, i_c`` corrected,
        ``theta_e`` turned back by the encoder offset (rad).
    """
    s = errors.summary
    use = lambda entries: all(e["identifiable"] is not False for e in entries)
    offset = errors.offset_a if use(s["current_offset_a"]) else np.zeros_like(errors.offset_a)
    gain = errors.gain if use(s["current_gain"]) else np.ones_like(errors.gain)
    delta = errors.encoder_offset_rad if s["encoder_offset_rad"]["identifiable"] else 0.0
    k = errors.offset_a.size
    m = np.stack([cols["i_a"], cols["i_b"]] + ([cols["i_c"]] if k == 3 else []), axis=1)
    i, _ = _true_currents(m, offset, gain)
    keep = ("time", "omega_m", "T_L", "U_dc", *sum(_STATOR_VOLTAGE_SETS.values(), ()))
    out = {n: cols[n] for n in keep if n in cols}
    out["i_a"], out["i_b"] = i[:, 0], i[:, 1]
    out["i_c"] = i[:, 2] if k == 3 else -i[:, 0] - i[:, 1]
    out["theta_e"] = np.mod(cols["theta_e"] - delta + np.pi, 2 * np.pi) - np.pi
    return out
