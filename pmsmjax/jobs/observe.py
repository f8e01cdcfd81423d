"""``pmsmjax observe``: a chapter 5 observer, or the rotating HF-injection estimator of chapter 6, run offline
on a recorded drive log ([`pmsmjax.recorded.offline_observer`][pmsmjax.recorded.offline_observer]), scored
against the log's truth columns when it has them.

``hfi-rotating`` reads the carrier from the log's voltages (``carrier="measured"``: the log's drive
injected it, this run does not), and its angle is the d axis modulo pi: the estimate is given in
[-pi/2, pi/2) and the errors are taken modulo pi, unless the polarity is known. ``hfi-pulsating`` and
``hybrid`` are refused ([`check_observer`][pmsmjax.jobs.observe.check_observer]).
"""

import dataclasses
import time
from collections.abc import Mapping, Sequence

import numpy as np

from pmsmjax.analysis.observer_errors import error_statistics
from pmsmjax.assemble import map_aware, spec_motor
from pmsmjax.estimators.registry import INJECTION_OBSERVERS, check_observer_name, make_observer
from pmsmjax.frames.three_phase import wrap_angle
from pmsmjax.io.drive_files import DriveSpec
from pmsmjax.recorded.offline_observer import observe
from pmsmjax.spec.validation import ParameterError


def check_observer(name: str, injection_flags: Sequence[str] = ()) -> None:
    """Refuse an observer that cannot run offline on a log, and `injection_flags` (the flags given that only
    HF injection takes, e.g. ``["--hf-voltage"]``) for one that injects nothing."""
    check_observer_name(name)
    if name == "hfi-pulsating":
        raise ParameterError(
            "observer 'hfi-pulsating' cannot run offline: its demodulation needs the injection axis of the "
            "drive that made the log, which a log does not record; use --observer hfi-rotating on logs "
            "with rotating injection."
        )
    if name == "hybrid":
        raise ParameterError(
            "observer 'hybrid' cannot run offline: it commands start-up polarity pulses and fades its "
            "carrier with its own speed estimate, which a recorded log cannot follow; run its parts, "
            "--observer hfi-rotating and a chapter 5 observer, on the log instead."
        )
    if injection_flags and name not in INJECTION_OBSERVERS:
        raise ParameterError(
            f"{', '.join(injection_flags)} apply to the HF-injection observer hfi-rotating only, not "
            f"{name!r}."
        )


@dataclasses.dataclass(frozen=True)
class ObserveSpec:
    """What to run: the `observer` by name on the `drive`'s motor (`motor`: the preset name or drive file
    as given, `log`: the log's path, both for the summary), its design-rule `options` overridden as given,
    the errors scored against `truth` (``theta_e``, ``omega_m``) after `settle_s` s. Injection only: the
    log's carrier `hf_voltage` (V) and `hf_frequency` (Hz), None for the design rule's; `polarity_known`
    scores the angle modulo 2 pi instead of pi. `observer_model`: on a drive file with a flux map,
    ``"map"`` (None: the default there) has the observer read the map
    ([`map_aware`][pmsmjax.assemble.map_aware]), as `demo` runs it; ``"constant"`` keeps the file's
    constant ``L_d``, ``L_q``, ``psi_f``."""

    observer: str
    drive: DriveSpec
    motor: str
    log: str
    settle_s: float = 0.05
    truth: tuple[str, ...] = ()
    options: Mapping[str, object] = dataclasses.field(default_factory=dict)
    hf_voltage: float | None = None
    hf_frequency: float | None = None
    polarity_known: bool = False
    observer_model: str | None = None


@dataclasses.dataclass(frozen=True)
class ObserveResult:
    """The estimate, one row per log row: `time` ``(N,)`` s, `theta_e` ``(N,)`` electrical rad in
    [-pi, pi) (the d axis in [-pi/2, pi/2) when `modulo_pi`), `omega_m` ``(N,)`` mechanical rad/s; the
    log's `truth` columns; `summary` (``observe.json``); `report`: the console's lines on the errors."""

    time: np.ndarray
    theta_e: np.ndarray
    omega_m: np.ndarray
    truth: Mapping[str, np.ndarray]
    modulo_pi: bool
    summary: dict
    report: tuple[str, ...]


def run_observer(spec: ObserveSpec, log) -> ObserveResult:
    """Run the observer of `spec` over `log` (a stator-frame log: ``time``, ``u_ab``, ``i_ab``, ``Ts``,
    ``truth``, ``n``, ``notes``, as
    [`tuning.identify.stator_log.StatorLog`][tuning.identify.stator_log.StatorLog]); a diverging estimate is
    refused ([`ParameterError`][pmsmjax.spec.validation.ParameterError])."""
    motor = spec_motor(spec.drive)
    injection = spec.observer in INJECTION_OBSERVERS
    options = dict(spec.options)
    if injection:
        # the log's drive injected the carrier: take its phase from the logged voltages
        options.setdefault("carrier", "measured")
        if spec.hf_voltage is not None:
            options["hf_voltage"] = spec.hf_voltage
        if spec.hf_frequency is not None:
            options["hf_frequency"] = spec.hf_frequency
    observer = make_observer(spec.observer, motor, log.Ts, **options)
    on_map = spec.drive.flux_map is not None and (spec.observer_model or "map") == "map"
    if on_map:
        observer = map_aware(observer, spec.drive)

    t0 = time.perf_counter()
    est = observe(observer, log.u_ab, log.i_ab, log.Ts)
    theta, omega = np.asarray(est.theta_e, dtype=np.float64), np.asarray(est.omega_m, dtype=np.float64)
    wall = time.perf_counter() - t0
    modulo_pi = injection and not spec.polarity_known
    if modulo_pi:
        theta = 0.5 * wrap_angle(2.0 * theta)  # the d axis modulo pi, [-pi/2, pi/2)
    bad_rows = ~(np.isfinite(theta) & np.isfinite(omega))
    if bad_rows.any():
        row = int(np.argmax(bad_rows))
        raise ParameterError(
            f"observer {spec.observer!r} diverged (not finite from row {row}, t = {log.time[row]:.6g} s); "
            "nothing written: check the motor parameters (--motor), the log's units (--units) and the "
            "observer options."
        )

    summary = {
        "observer": spec.observer,
        "motor": spec.motor,
        "drive_file": spec.drive.summary(),
        "log": spec.log,
        "samples": int(log.n),
        "Ts_s": log.Ts,
        "options": options,
        "notes": list(log.notes),
        "wall_time_s": wall,
        "angle_modulo_pi": bool(modulo_pi),
        "observer_model": "map" if on_map else "constant",
    }
    report = ()
    if spec.truth:
        e = summary["errors"] = _errors(log, theta, omega, spec.settle_s, modulo_pi)
        parts = []
        if "angle_rms_deg" in e:
            parts.append(f"angle error {e['angle_rms_deg']:.3g} deg RMS (max {e['angle_max_deg']:.3g})")
        if "speed_rms_rpm" in e:
            parts.append(f"speed error {e['speed_rms_rpm']:.3g} r/min RMS")
        report = (f"after {spec.settle_s:g} s: " + ", ".join(parts),)
    return ObserveResult(log.time, theta, omega, log.truth, bool(modulo_pi), summary, report)


def _errors(log, theta, omega, settle_s, modulo_pi=False) -> dict:
    """Error figures against the truth columns present (angle: electrical deg; speed: mechanical r/min)."""
    if log.time[-1] - log.time[0] <= settle_s:
        raise ParameterError(
            f"--settle-s {settle_s} s is not shorter than the log ({log.time[-1] - log.time[0]:.4g} s): "
            "lower it so some samples are scored."
        )
    th_true = log.truth.get("theta_e", theta)
    w_true = log.truth.get("omega_m", omega)
    stats = error_statistics(log.time, theta, omega, th_true, w_true, settle_s, modulo_pi=modulo_pi)
    keys = {"samples"}
    if "theta_e" in log.truth:
        keys |= {"angle_rms_deg", "angle_mean_deg", "angle_max_deg"}
    if "omega_m" in log.truth:
        keys |= {"speed_rms_rpm", "speed_max_rpm"}
    out = {k: v for k, v in stats.items() if k in keys}
    out["settle_s"] = float(settle_s)
    out["finite"] = bool(np.all(np.isfinite(list(out.values()))))
    return out
