"""Identification of an imperfect drive, against an ideal-model fit of the same log.

The log is the heat run of [`tuning.identify.heat_run_log`][tuning.identify.heat_run_log] (SciPy's DOP853
and LSODA, not the engine): a warm motor (R +0.393 %/K, psi_f -0.11 %/K, one thermal node), two current
sensors with offsets and a gain mismatch, an encoder turned by 6.9 deg, 0.5 V of dead time, recorded in 50
captures over 1500 s, written as a CSV as a scope would. Two commands identify it:

- ``pmsmjax identify LOG --sensor-errors --dead-time --pole-pairs 4 --fix J=... --fix B=...`` (the drive as
  it is: the log's temperature column switches on R(T), psi_f(T) and the thermal network);
- ``pmsmjax identify IDEAL_LOG --pole-pairs 4 ...``, the same log without its temperature column, and no
  sensor errors or dead time: an ideal-model fit.

Prints (and writes with ``--json``) each value against the truth. R, L_d, L_q, the network are compared
with the values per ampere as sensor a reads it (a log cannot give sensor a's absolute gain; the test
``tests/tuning/test_identify_temperature.py`` says why).

``python -m benchmarks.real_drive_identification [--json FILE]``
"""

import argparse
import json
import math
import tempfile
import time
from pathlib import Path

from benchmarks.bench_core import machine_info, publish
from pmsmjax.cli import main as pmsmjax
from pmsmjax.io.logs import write_csv_atomic
from tuning.identify.heat_run_log import DEAD_TIME_V, MOTOR, SENSORS, THERMAL, heat_run_log

#: The rotor is held at constant speed by a dynamometer in each capture: J and B are not in this log.
MECHANICS = ["--fix", "J=0.001", "--fix", "B=0.0001", "--load", "none"]


def _identify(log: Path, out: Path, extra: list) -> tuple[dict, float]:
    argv = ["identify", str(log), "--out", str(out), "--pole-pairs", str(MOTOR["pole_pairs"]), *MECHANICS]
    start = time.perf_counter()
    if pmsmjax([*argv, *extra, "--no-figures"]) not in (0, 1):
        raise SystemExit(f"identify {' '.join(extra)} failed")
    return json.loads((out / "params.json").read_text()), time.perf_counter() - start


def run(folder: Path) -> dict:
    cols = heat_run_log()
    g_a = SENSORS["current_gain"][0]
    log, ideal_log = folder / "heat_run.csv", folder / "heat_run_no_temperature.csv"
    write_csv_atomic(log, cols)
    write_csv_atomic(ideal_log, {k: v for k, v in cols.items() if k != "temperature_c"})
    real, real_s = _identify(log, folder / "real", ["--sensor-errors", "--dead-time"])
    ideal, ideal_s = _identify(ideal_log, folder / "ideal", [])
    p, t, s = real["parameters"], real["temperature"], real["sensor_errors"]
    rows = [  # (name, truth, identified, ideal fit, unit)
        ("R at 20 degC", MOTOR["R"] / g_a, p["R"]["value"], ideal["parameters"]["R"]["value"], "ohm"),
        ("L_d", MOTOR["L_d"] / g_a, p["L_d"]["value"], ideal["parameters"]["L_d"]["value"], "H"),
        ("L_q", MOTOR["L_q"] / g_a, p["L_q"]["value"], ideal["parameters"]["L_q"]["value"], "H"),
        (
            "psi_f at 20 degC",
            MOTOR["psi_f"],
            p["psi_f"]["value"],
            ideal["parameters"]["psi_f"]["value"],
            "Wb",
        ),
        ("R temp. coeff.", MOTOR["r_temp_coeff_per_k"], t["r_temp_coeff_per_k"]["value"], 0.0, "1/K"),
        (
            "psi_f temp. coeff.",
            MOTOR["psi_f_temp_coeff_per_k"],
            t["psi_f_temp_coeff_per_k"]["value"],
            0.0,
            "1/K",
        ),  # fmt: skip
        ("R_th", THERMAL["r_th_k_per_w"] / g_a, t["thermal_network"]["r_th_k_per_w"]["value"], None, "K/W"),
        ("C_th", THERMAL["c_th_j_per_k"] * g_a, t["thermal_network"]["c_th_j_per_k"]["value"], None, "J/K"),
        ("offset a", SENSORS["current_offset_a"][0], s["current_offset_a"][0]["value"], 0.0, "A"),
        ("offset b", SENSORS["current_offset_a"][1], s["current_offset_a"][1]["value"], 0.0, "A"),
        ("gain b / a", SENSORS["current_gain"][1] / g_a, s["current_gain"][1]["value"], 1.0, ""),
        (
            "encoder offset",
            math.degrees(SENSORS["encoder_offset_rad"]),
            s["encoder_offset_rad"]["value_deg"],
            0.0,
            "deg",
        ),  # fmt: skip
        ("V_dt", DEAD_TIME_V, real["extra_parameters"]["V_dt"]["value"], 0.0, "V"),
    ]
    table = []
    for name, truth, got, naive, unit in rows:
        error = lambda v, truth=truth, unit=unit: (
            None if v is None else (v - truth if unit in ("A", "deg") else v / truth - 1.0)
        )
        table.append({"name": name, "unit": unit, "truth": truth, "identified": got, "error": error(got),
                      "ideal_fit": naive, "ideal_error": error(naive)})  # fmt: skip
    seconds = {"identify": real_s, "identify_ideal": ideal_s}
    return {"rows": table, "seconds": seconds, "log_rows": int(cols["time"].size)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", default=None, help="write the results to this JSON file")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        result = run(Path(tmp))
    result["machine"] = machine_info()
    lines = [f"{'':20s} {'truth':>12s} {'identified':>12s} {'error':>9s} {'ideal fit':>12s} {'error':>9s}"]
    for r in result["rows"]:
        rel = r["unit"] not in ("A", "deg")
        fmt = lambda e, rel=rel: "" if e is None else (f"{100 * e:+.3f} %" if rel else f"{e:+.4f}")
        naive = "" if r["ideal_fit"] is None else f"{r['ideal_fit']:.6g}"
        lines.append(
            f"{r['name']:20s} {r['truth']:12.6g} {r['identified']:12.6g} {fmt(r['error']):>9s} "
            f"{naive:>12s} {fmt(r['ideal_error']):>9s}  {r['unit']}"
        )
    sec = result["seconds"]
    lines.append(
        f"identify: {sec['identify']:.1f} s (ideal fit {sec['identify_ideal']:.1f} s), "
        f"{result['log_rows']} rows"
    )
    publish(result, "\n".join(lines), args.json)


if __name__ == "__main__":
    main()
