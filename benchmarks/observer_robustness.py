"""The observers' robustness table: a sensorless Monte Carlo study (``pmsmjax montecarlo --estimator NAME``)
per chapter 5 observer, summarised as one Markdown table.

Each study draws the plant's R (+-30 %), L_d, L_q (+-20 % each) and psi_f (+-10 %), uniform, while the
observer and the controller keep the nominal motor ([`tuning.montecarlo.study`][tuning.montecarlo.study]), and
runs the book scenario form sensorless from standstill (I/f start). Per observer: percentiles over the runs of
the per-run angle error RMS and max after 50 ms (electrical degrees), of the speed estimation error RMS
(r/min), the loss-of-lock rate ([`pmsmjax.analysis.observer_errors`][pmsmjax.analysis.observer_errors]), the
speed-tracking failure rate (``|mean speed error|`` over the last 10 % of the run above 10 r/min) and the rate
of any failure, and the study's run time (compile excluded; 0 when its chunks were loaded from an earlier
run).

    python -m benchmarks.observer_robustness --n 1000 --out OUT [--speed-rpm 1000]

Each study's folder ``OUT/NAME`` holds its summary.json and chunks (a rerun loads them). Same as running
``pmsmjax montecarlo --estimator NAME --n N --sensitivity-runs 0 --out OUT/NAME`` per observer (with
``[scenario] speed_rpm`` in a --config file for another speed).
"""

import argparse
import time

OBSERVERS = ("smo", "smo-pll", "adaptive-smo", "dq-smo", "mras", "ekf")


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=1000)
    p.add_argument("--out", default="observer_robustness_out")
    p.add_argument("--speed-rpm", type=float, default=1000.0)
    p.add_argument("--observers", default=",".join(OBSERVERS))
    args = p.parse_args(argv)

    from tuning.montecarlo import split_cpu

    split_cpu(None)
    from tuning.montecarlo import Study, run_study

    rows = []
    for name in args.observers.split(","):
        study = Study(n=args.n, estimator=name, speed_rpm=args.speed_rpm, sensitivity_runs=0)
        t0 = time.perf_counter()
        s = run_study(study, f"{args.out}/{name}", progress=False, figures=False)
        wall = time.perf_counter() - t0
        m, f = s["metrics"], s["failures"]
        rows.append(
            f"| {name} | {m['angle_error_rms_deg']['p50']:.2f} | {m['angle_error_rms_deg']['p95']:.2f} | "
            f"{m['angle_error_max_deg']['p95']:.2f} | {m['speed_error_rms_rpm']['p95']:.1f} | "
            f"{100 * f['lock_lost']['rate']:.1f} | {100 * f['speed_tracking']['rate']:.1f} | "
            f"{100 * f['any']['rate']:.1f} | {s['run_time_s']:.1f} / {wall:.0f} |"
        )
        print(rows[-1], flush=True)
    print(
        f"\n{args.n} draws per observer, book scenario at {args.speed_rpm:g} r/min, 10 N m at 0.2 s, 0.4 s\n"
    )
    print(
        "| observer | angle RMS p50 (el. deg) | angle RMS p95 | angle max p95 | speed-est. RMS p95 (r/min) "
        "| loss of lock % | tracking failures % | any failure % | run / wall s |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))


if __name__ == "__main__":
    main()
