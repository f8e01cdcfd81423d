"""Where each sensorless method loses the angle on the strongly saturated machine (the saturated-ipm
drive file, whose q axis saturates about 4x): steady angle and speed error against the load current, with
the constant-parameter model and with the flux map's model, in float64.

- Fundamental-model observers (``smo``, ``smo-pll``, ``adaptive-smo``, ``dq-smo``, ``mras``, ``ekf``) at
  an imposed 1000 r/min, current control with ``i_d* = 0`` and ``i_q*`` stepped at 50 ms to each load;
  "constant": the design rule's model, the drive file's linear model (the map's incremental inductances
  at the rated 10 A); "map": the same observer with its model scheduled on the map
  ([`pmsmjax.estimators.map_scheduled`][pmsmjax.estimators.map_scheduled]); the MRAS also with a 30 rad/s
  operating-current filter ("map, slow current").
- HF injection (``hfi-rotating``, ``hfi-pulsating``) at standstill with ``i_d* = -3 A`` (so the map
  cross-saturates) and the same ``i_q*``; designed for the no-load small-signal inductances; "map": the
  cross-saturation angle taken out
  ([`pmsmjax.estimators.hfi_cross_saturation`][pmsmjax.estimators.hfi_cross_saturation]).

"predicted (constant)": the constant model's steady error from the map alone, no simulation (the
steady-state voltage equation for the observers, the smallest-inductance axis for HF injection; "no
lock": none within 90 degrees).

The observers start 0.3 rad off; the errors are the mean (and peak-to-peak) over the last 100 ms of 0.3 s.
HF injection's angle is modulo pi. "lost": a peak-to-peak over 20 degrees or a mean over 45 degrees;
"p-p": the peak-to-peak where it is over 1 degree.

    python -m benchmarks.flux_map_observers [--json out.json]
"""

import argparse
import math

import jax

jax.config.update("jax_enable_x64", True)

import equinox as eqx  # noqa: E402
import numpy as np  # noqa: E402

from benchmarks.bench_core import publish  # noqa: E402
from pmsmjax import presets  # noqa: E402
from pmsmjax.analysis.observer_errors import angle_error, angle_error_modulo_pi  # noqa: E402
from pmsmjax.assemble import spec_drive, spec_flux_map, spec_motor  # noqa: E402
from pmsmjax.estimators import INJECTION_OBSERVERS, OBSERVERS  # noqa: E402
from pmsmjax.estimators.hfi_cross_saturation import (  # noqa: E402
    cross_saturation_compensated,
    injection_model,
    predicted_angle_error,
)
from pmsmjax.estimators.map_scheduled import constant_model_angle_error, map_scheduled  # noqa: E402
from pmsmjax.io.drive_files import drive_spec  # noqa: E402
from pmsmjax.io.flux_map_files import read_flux_map  # noqa: E402
from pmsmjax.scenarios import Profile, Scenario, stack_scenarios  # noqa: E402
from pmsmjax.simulate import simulate  # noqa: E402
from pmsmjax.units import rpm_to_rad_s  # noqa: E402

#: q-axis load currents, A: none, light, half rated... the rated 10 A and the 25 A maximum.
LOADS = (0.0, 2.0, 5.0, 10.0, 25.0)
SPEED = rpm_to_rad_s(1000.0)
HFI_I_D = -3.0
DURATION_S = 0.3
STEADY = 1000  # periods scored (100 ms at 10 kHz)
LOST_PTP_DEG, LOST_MEAN_DEG = 20.0, 45.0
#: The MRAS's extra row: operating-current low-pass, rad/s
#: ([`pmsmjax.estimators.map_scheduled`][pmsmjax.estimators.map_scheduled]).
MRAS_CURRENT_CUTOFF = 30.0


def _score(drive, speed, i_d, modulo_pi):
    scenarios = stack_scenarios(
        [
            Scenario(
                DURATION_S,
                speed_ref=Profile.constant(speed),
                id_ref=Profile.step(0.05, 0.0, i_d),
                iq_ref=Profile.step(0.05, 0.0, i_q),
            )
            for i_q in LOADS
        ]
    )
    init = drive.init(speed_m=speed, theta_e=0.3)
    tr = eqx.filter_jit(jax.vmap(lambda s: simulate(drive, s, initial_state=init)))(scenarios)
    error = angle_error_modulo_pi if modulo_pi else angle_error
    e = np.degrees(np.asarray(error(tr.theta_e_est, tr.theta_e)))[:, -STEADY:]
    dw = np.asarray(tr.omega_m_est - tr.omega_m)[:, -STEADY:].mean(1)
    rows = []
    for k in range(len(LOADS)):
        mean, ptp = float(e[k].mean()), float(np.ptp(e[k]))
        lost = ptp > LOST_PTP_DEG or abs(mean) > LOST_MEAN_DEG
        rows.append({"angle_deg": mean, "ptp_deg": ptp, "speed_err_rad_s": float(dw[k]), "lost": lost})
    return rows


def run() -> dict:
    spec = drive_spec("saturated-ipm")
    grid = read_flux_map(spec.motor["flux_map"])
    motor, flux_map = spec_motor(spec), spec_flux_map(spec)
    base = spec_drive(spec, mode="current", mechanics="imposed")
    out = {"loads_a": list(LOADS), "speed_rpm": 1000.0, "hfi_i_d_a": HFI_I_D, "methods": {}}
    for name in OBSERVERS:
        drive = presets.with_observer(base, name, motor, None, startup=False)
        scheduled = eqx.tree_at(lambda d: d.estimator, drive, map_scheduled(drive.estimator, flux_map))
        predicted = [
            math.degrees(constant_model_angle_error(grid, float(motor.L_q), (0.0, q))[0]) for q in LOADS
        ]
        out["methods"][name] = {
            "constant": _score(drive, SPEED, 0.0, False),
            "map": _score(scheduled, SPEED, 0.0, False),
            "predicted_constant_deg": predicted,
        }
        if name == "mras":  # its model changing every sample excites it: a slower operating current
            slow = map_scheduled(drive.estimator, flux_map, MRAS_CURRENT_CUTOFF)
            out["methods"][name]["map, slow current"] = _score(
                eqx.tree_at(lambda d: d.estimator, drive, slow), SPEED, 0.0, False
            )
    model = injection_model(grid, motor, (0.0, 0.0))
    for name in INJECTION_OBSERVERS:
        drive = presets.with_observer(base, name, model, None, startup=False)
        compensated = eqx.tree_at(
            lambda d: d.estimator, drive, cross_saturation_compensated(drive.estimator, flux_map)
        )
        predicted = [math.degrees(predicted_angle_error(grid, (HFI_I_D, q))[0]) for q in LOADS]
        out["methods"][name] = {
            "constant": _score(drive, 0.0, HFI_I_D, True),
            "map": _score(compensated, 0.0, HFI_I_D, True),
            "predicted_constant_deg": predicted,
        }
    return out


#: Peak-to-peak above this (degrees) is shown next to the mean: an oscillation the mean hides.
SHOW_PTP_DEG = 1.0


def _cell(r: dict) -> str:
    if r["lost"]:
        return "lost"
    ptp = f" (p-p {r['ptp_deg']:.1f})" if r["ptp_deg"] > SHOW_PTP_DEG else ""
    return f"{r['angle_deg']:+.2f}{ptp}"


def format_table(r: dict) -> str:
    head = " | ".join(f"{q:g} A" for q in r["loads_a"])
    lines = [
        "Steady angle error, electrical degrees (mean of the last 100 ms), against the q load current; "
        f"fundamental observers at {r['speed_rpm']:g} r/min, i_d* = 0; HF injection at standstill, "
        f"i_d* = {r['hfi_i_d_a']:g} A (modulo pi).",
        "",
        f"| method | model | {head} |",
        "|" + "---|" * (2 + len(r["loads_a"])),
    ]
    for name, m in r["methods"].items():
        for model in [k for k in m if k != "predicted_constant_deg"]:
            cells = " | ".join(_cell(x) for x in m[model])
            lines.append(f"| {name} | {model} | {cells} |")
        cells = " | ".join("no lock" if math.isnan(x) else f"{x:+.2f}" for x in m["predicted_constant_deg"])
        lines.append(f"| {name} | predicted (constant) | {cells} |")
    return "\n".join(lines)


def main(json_path: str | None = None) -> dict:
    results = run()
    return publish(results, format_table(results), json_path)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="sensorless methods on the saturated-ipm flux map (table)")
    parser.add_argument("--json", help="write the figures to this JSON file")
    main(parser.parse_args().json)
