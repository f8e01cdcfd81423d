"""Per-period cost of imperfect sensors against the ideal book drive, timed in one run.

``python -m benchmarks.sensor_cost [--quick]``: the book scenario (1000 r/min, 10 N m half way; float32) on
the book drive with ideal sensors, with two current sensors carrying offsets and gains
([`CurrentSensors`][pmsmjax.estimators.current_sensors.CurrentSensors]), with those and a 10 mA ADC step,
and on an encoder (2500 lines) without and with a mounting offset, and all of those on a warm motor
([`WindingThermal`][pmsmjax.machines.thermal.WindingThermal]). Calls are timed interleaved
([`time_interleaved`][pmsmjax.jobs.bench.time_interleaved]), so each ratio holds under a varying load;
compile time is reported apart from run time.
"""

import argparse

import jax

from benchmarks.bench_core import compile_time, machine_info, time_interleaved
from pmsmjax import presets, simulate
from pmsmjax.assemble import with_parts
from pmsmjax.estimators import Encoder
from pmsmjax.estimators.current_sensors import CurrentSensors
from pmsmjax.machines.thermal import WindingThermal

#: A warm winding (the first issue of a real drive together with its sensors): copper and NdFeB
#: coefficients, a 1 K/W, 300 J/K node started at 80 degC.
WARM = WindingThermal(r_th=1.0, c_th=300.0, ambient_k=298.15, initial_k=353.15, reference_k=293.15,
                      r_temp_coeff=0.00393, psi_f_temp_coeff=-0.0011)  # fmt: skip


def measure(quick: bool = False) -> dict:
    """``{name: {run_s, compile_s, us_per_period, vs_ideal}}`` and the run's settings."""
    duration = 0.02 if quick else 0.5
    scenario = presets.book_scenario(duration_s=duration, load_time_s=duration / 2)
    ideal = presets.book_drive()
    sensors = CurrentSensors([0.11, -0.07], [1.0, 1.018])
    adc = CurrentSensors([0.11, -0.07], [1.0, 1.018], lsb_a=0.01)
    drives = {
        "ideal": ideal,
        "current offset+gain": with_parts(ideal, {"current_sensor": sensors}),
        "current offset+gain+ADC": with_parts(ideal, {"current_sensor": adc}),
        "encoder": with_parts(ideal, {"estimator": Encoder(2500, 4)}),
        "encoder+offset, current offset+gain+ADC": with_parts(
            ideal, {"estimator": Encoder(2500, 4, offset_rad=0.09), "current_sensor": adc}
        ),
        "warm, encoder+offset, current offset+gain+ADC": with_parts(
            ideal, {"estimator": Encoder(2500, 4, offset_rad=0.09), "current_sensor": adc, "thermal": WARM}
        ),
    }
    calls = {name: (lambda d=d: jax.block_until_ready(simulate(d, scenario))) for name, d in drives.items()}
    first, best = time_interleaved(calls, 1 if quick else 7)
    periods = round(duration / ideal.Ts)
    out = {
        name: {
            "run_s": best[name],
            "compile_s": compile_time(first[name], best[name]),
            "us_per_period": 1e6 * best[name] / periods,
        }
        for name in calls
    }
    for o in out.values():
        o["vs_ideal"] = o["us_per_period"] / out["ideal"]["us_per_period"]
    for name in ("encoder+offset, current offset+gain+ADC", "warm, encoder+offset, current offset+gain+ADC"):
        out[name]["vs_encoder"] = out[name]["us_per_period"] / out["encoder"]["us_per_period"]
    return {"drives": out, "duration_s": duration, "machine": machine_info()}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="0.02 s, one round (a smoke test)")
    r = measure(parser.parse_args(argv).quick)
    print(
        f"sensor errors vs ideal sensors, book scenario ({r['duration_s']:g} s), best of rounds;",
        r["machine"],
    )
    print(f"{'drive':46s} {'run ms':>8s} {'compile s':>9s} {'us/period':>9s} {'x ideal':>8s}")
    for name, o in r["drives"].items():
        print(
            f"{name:46s} {1e3 * o['run_s']:8.2f} {o['compile_s']:9.2f} {o['us_per_period']:9.3f} "
            f"{o['vs_ideal']:8.3f}" + (f"  ({o['vs_encoder']:.3f} x encoder)" if "vs_encoder" in o else "")
        )


if __name__ == "__main__":
    main()
