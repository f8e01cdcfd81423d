"""``pmsmjax tune --anticogging``: learn a drive's anticogging table
([`learn_anticogging`][tuning.autotune.anticogging.learn_anticogging]) and write it beside the gains:
``DIR/anticogging.csv`` ([`pmsmjax.io.anticogging_files`][pmsmjax.io.anticogging_files]) and
``DIR/anticogging.json`` (the ripple before and after, the runs, the solver's steps)."""

import json
import time
from pathlib import Path

from pmsmjax.io.anticogging_files import read_anticogging_csv, write_anticogging_csv
from pmsmjax.io.logs import atomic_write
from tuning.autotune.anticogging import learn_anticogging

__all__ = ["run_anticogging_job"]


def run_anticogging_job(
    out, spec, control: str = "pi", *, n_bins: int = 128, speed_rpm: float = 30.0, max_steps: int = 3
) -> dict:
    """Learn the table of ``spec``'s drive and write ``out/anticogging.csv`` and ``out/anticogging.json``.

    Args:
        out: Output folder (created).
        spec: The drive file ([`DriveSpec`][pmsmjax.spec.drive_spec.DriveSpec], with ``[harmonics]``).
        control: The FOC control method its drive runs (``"pi"`` or ``"smc"``).
        n_bins: Bins over one electrical revolution.
        speed_rpm: The speed the ripple is minimised at, r/min.
        max_steps: Gauss-Newton steps at most.

    Returns:
        What ``anticogging.json`` holds.
    """
    from pmsmjax.assemble import assemble

    drive = assemble(spec, control)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    result = learn_anticogging(drive, n_bins=n_bins, speed_rpm=speed_rpm, max_steps=max_steps)
    path = write_anticogging_csv(out / "anticogging.csv", result.table.iq_a)
    read_anticogging_csv(path)  # what is written must read back
    runs = result.runs
    data = {
        "table": "anticogging.csv: theta_e_rad (bin angle over one electrical revolution), iq_a (A)",
        "n_bins": n_bins,
        "speed_rpm": speed_rpm,
        "runs": {
            "start_angles_rad": [float(a) for a in runs.start_angles],
            "settle_s": runs.settle_s,
            "window_s": runs.window_s,
        },
        "speed_error_before_rpm": result.before,
        "speed_error_after_rpm": result.after,
        "rms_cut": result.rms_cut,
        "peak_to_peak_cut": result.peak_to_peak_cut,
        "solver": "optimistix Gauss-Newton, forward-mode Jacobian through the closed loop",
        "steps": result.steps,
        "wall_time_s": time.perf_counter() - start,
    }
    atomic_write(out / "anticogging.json", lambda f: json.dump(data, f, indent=2), mode="w")
    return data
