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

**Formulation.** One nonlinear least-squares fit of the stator voltage equation integrated over blocks
of the log ([`tuning.identify.stator_frame_fit`][tuning.identify.stator_frame_fit]), with R, L_d, L_q,
psi_f, the offsets, the gains relative to sensor a and the encoder offset ``delta`` as unknowns (and, given
a ``temperature_c`` column, the temperature coefficients of R and psi_f). The encoder offset is fitted
jointly with the machine instead of read off a zero crossing of the back-EMF (the usual encoder-offset
calibration at standstill locks the rotor with a d-axis current, as ODrive's
``ENCODER_OFFSET_CALIBRATION`` and TI's SPRABZ0 do; with the back-EMF it is the angle of the no-load
voltage against the counted angle). At speed the fit separates ``delta`` from the ``L_q i_q`` cross term
because the log's currents vary (steps of i_d and i_q, two speeds). With three sensors the sampled
currents must also sum to zero (Kirchhoff), which adds a residual per sample and pins the offsets' common
part, which the amplitude-invariant Clarke transform drops. The fit is SciPy's Levenberg-Marquardt from
the linear start; the covariance is the identification's sandwich with Newey-West lags
([`tuning.identify.uncertainty.covariance`][tuning.identify.uncertainty.covariance]) and 95 % intervals are
1.96 standard errors. A log recorded in bursts is cut into blocks capture by capture.

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
from tuning.identify.flux_harmonics_fit import flux_harmonics_summary
from tuning.identify.log_columns import (
    VOLTAGE_SETS,
    apply_units,
    check_grid,
    pick_set,
    segment_bounds,
    to_dq64,
)
from tuning.identify.stator_frame_fit import StatorFrameProblem, central_jacobian, noise_level, true_currents
from tuning.identify.temperature_coefficients import temperature_summary
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
        segments: ``(S + 1,)`` first row of each capture and the row count (one capture: ``[0, N]``).
        temperature_c: ``(N,)`` winding temperature, degC, or None.
    """

    time: np.ndarray
    u_ab: np.ndarray
    m: np.ndarray
    theta_m: np.ndarray
    source: str = "log"
    segments: np.ndarray | None = None
    temperature_c: np.ndarray | None = None

    def __post_init__(self):
        if self.segments is None:
            object.__setattr__(self, "segments", np.array([0, self.time.size]))

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
    source: str = "log", pole_pairs: int | None = None,
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
        pole_pairs: The motor's pole pairs, for a speed in erpm.

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
    optional = [n for n in ("i_c", "omega_m", "T_L", "U_dc", "temperature_c") if n not in need]
    c = check_columns(cols, need, optional, source=source)
    apply_units(c, units or {}, source, pole_pairs)
    c, _, _ = check_grid(c, np.diff(c["time"]), resample, source, bursts=True)
    with jax.enable_x64(True):
        u_ab = to_dq64(c, _STATOR_VOLTAGE_SETS[vset], vset, np.zeros_like(c["time"]), u_dc)
    phases = [c["i_a"], c["i_b"]]
    if "i_c" in c:
        total = c["i_a"] + c["i_b"] + c["i_c"]
        scale = max(float(np.max(np.abs(c["i_a"]))), 1e-12)
        if np.max(np.abs(total)) > 1e-9 * scale:
            phases.append(c["i_c"])
    log = SensorLog(
        c["time"], np.asarray(u_ab), np.stack(phases, axis=1), c["theta_e"], source,
        segments=segment_bounds(c["time"]), temperature_c=c.get("temperature_c"),
    )  # fmt: skip
    return log, c


def identify_sensor_errors(
    log: SensorLog, block: int = 50, reference_c: float = 20.0, dead_time: bool = False, flux_orders=()
) -> SensorErrors:
    """Fit the current-sensor offsets, their relative gains and the encoder offset (module docstring);
    with a temperature column, also R and psi_f at ``reference_c`` and their temperature coefficients.

    Args:
        log: The stator-frame log
            ([`sensor_log_from_columns`][tuning.identify.sensor_errors.sensor_log_from_columns]).
        block: Log intervals per integration block.
        reference_c: The temperature R and psi_f are stated at, degC (used with a temperature column).
        dead_time: Fit the inverter's error voltage with them (``V_dt``, V per phase): without it an
            uncorrected dead time biases the offsets.
        flux_orders: Orders of magnet flux harmonics fitted with them
            ([`tuning.identify.flux_harmonics_fit`][tuning.identify.flux_harmonics_fit]); the summary then
            has ``flux_harmonics`` and the machine ``flux_harmonics`` (complex amplitudes, Wb).

    Returns:
        The [`SensorErrors`][tuning.identify.sensor_errors.SensorErrors], with intervals in its summary.

    Raises:
        ParameterError: For a log too short for the blocks, or a fit that fails numerically.
    """
    pr = StatorFrameProblem(log, block, reference_c, dead_time, flux_orders=flux_orders)
    p0 = pr.start()
    i_rms = float(np.sqrt(np.mean(log.m**2)))
    n = pr.n_machine
    scale = np.abs(p0)
    scale[4:n] = np.maximum(scale[4:n], 1e-4)  # temperature coefficients (1/K), V_dt (V)
    scale[n : n + pr.k] = max(0.01 * i_rms, 1e-3)
    scale[n + pr.k :] = 1.0  # gains and the angle: order one
    sigma_i = noise_level(log.m)
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
    J = central_jacobian(lambda x: pr.residuals(x * scale, w_v), x) / scale  # per unit of each parameter
    r = pr.residuals(p, w_v)
    groups = [(J[: 2 * pr.n_b], r[: 2 * pr.n_b], (1, pr.n_b), 3)]
    if pr.k == 3:
        n_k = r.size - 2 * pr.n_b
        groups.append((J[2 * pr.n_b :], r[2 * pr.n_b :], (1, n_k), 1))
    if not np.all(np.isfinite(p)):
        raise ParameterError(f"{log.source}: the sensor-error fit failed numerically (non-finite values).")
    cov = covariance(groups)[0]
    se = np.sqrt(np.abs(np.diag(cov)))
    result = _result(pr, p, se, sol, w_v, log)
    if pr.flux_orders:
        result.summary["flux_harmonics"] = flux_harmonics_summary(pr, p, cov)
        result.machine["flux_harmonics"] = (pr.flux_orders, pr.unpack(p)["flux_h"])
    return result


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


def _result(pr: StatorFrameProblem, p, se, sol, w_v, log) -> SensorErrors:
    v = pr.unpack(p)
    R, L_d, L_q, psi_f, offset, gain = (v[n] for n in ("R", "L_d", "L_q", "psi_f", "offset", "gain"))
    delta = float(math.remainder(v["delta"], 2 * math.pi))
    k, n = pr.k, pr.n_machine
    lim = IDENTIFIABLE_STDERR
    offsets = [
        _entry(offset[j], se[n + j], "A", lim["current_offset_a"]) | {"sensor": "abc"[j]} for j in range(k)
    ]
    gains = [{"value": 1.0, "stderr": 0.0, "ci95": [1.0, 1.0], "unit": "", "identifiable": None,
              "sensor": "a", "note": "the reference: the gains are relative to sensor a"}]  # fmt: skip
    gains += [
        _entry(gain[j], se[n - 1 + k + j], "", lim["current_gain"] * gain[j]) | {"sensor": "abc"[j]}
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
    if pr.thermal:
        summary["temperature"] = temperature_summary(pr, p, se, log)
        machine |= {"r_temp_coeff_per_k": float(v["alpha"]), "psi_f_temp_coeff_per_k": float(v["beta"])}
    if pr.dead_time:
        machine["V_dt"] = float(v["V_dt"])
        summary["machine_of_this_fit"]["V_dt"] = float(v["V_dt"])
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
    i, _ = true_currents(m, offset, gain)
    keep = ("time", "omega_m", "T_L", "U_dc", *sum(_STATOR_VOLTAGE_SETS.values(), ()))
    out = {n: cols[n] for n in keep if n in cols}
    out["i_a"], out["i_b"] = i[:, 0], i[:, 1]
    out["i_c"] = i[:, 2] if k == 3 else -i[:, 0] - i[:, 1]
    out["theta_e"] = np.mod(cols["theta_e"] - delta + np.pi, 2 * np.pi) - np.pi
    return out
