"""The hybrid estimator's reference table and the contrasts behind its design.

Runs ([`pmsmjax.jobs.hybrid_runs`][pmsmjax.jobs.hybrid_runs]): the book drive on the salient book motor with
d-axis saturation, sensorless with the hybrid from standstill at 8 initial rotor angles (every 45 degrees, so
the injection alone locks to the wrong pole for about half), through

- ``book``: 1000 r/min step, 10 N m load step at 0.2 s;
- ``reversal``: -1000 r/min, 5 N m from 0.15 s, step to +1000 r/min at 0.3 s.

Variants: the default hybrid (injection ``hfi-rotating`` with polarity pulses, ``ekf`` above a 50-150 r/min
band, carrier gone at 250 r/min); other bands; ``smo-pll`` as the observer; no polarity pulses.
Columns: worst-case over the angles of max and RMS angle error after the start-up (60 ms, electrical
degrees), final speed error (r/min), how many of the runs held lock (max error < 90 degrees).

    python -m benchmarks.hybrid_table            (about 2 minutes on 2 CPU cores)
"""

import argparse

import jax
import numpy as np

from pmsmjax.jobs.hybrid_runs import hybrid_book_drive, hybrid_scenarios, run_from_angles, summary

VARIANTS = {
    "default: ekf 50/150/250 r/min": {},
    "ekf 30/100/200 r/min": dict(low_rpm=30.0, high_rpm=100.0, off_rpm=200.0),
    "ekf 80/200/300 r/min": dict(low_rpm=80.0, high_rpm=200.0, off_rpm=300.0),
    "smo-pll 50/150/250 r/min": dict(observer="smo-pll"),
    "smo-pll 150/250/350 r/min": dict(observer="smo-pll", low_rpm=150.0, high_rpm=250.0, off_rpm=350.0),
    "no polarity pulses": dict(polarity=False),
    "hfi-pulsating injection": dict(injection="hfi-pulsating"),
}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--variants", default=",".join(VARIANTS), help="comma-separated variant names (default: all)"
    )
    args = parser.parse_args(argv)
    jax.config.update("jax_enable_x64", True)
    angles = np.arange(8) * 2.0 * np.pi / 8.0
    print("| variant | scenario | max err (deg) | RMS err (deg) | final speed err (r/min) | locked |")
    print("|---|---|---|---|---|---|")
    for name in args.variants.split(","):
        drive = hybrid_book_drive(**VARIANTS[name])
        for scenario_name, scenario in hybrid_scenarios().items():
            s = summary(run_from_angles(drive, scenario, angles))
            print(
                f"| {name} | {scenario_name} | {s['max_deg'].max():.1f} | {s['rms_deg'].max():.2f} | "
                f"{np.abs(s['final_speed_error_rpm']).max():.1f} | {int(s['locked'].sum())}/{len(angles)} |"
            )


if __name__ == "__main__":
    main()
