"""The heat run of [`tuning.identify.heat_run_log`][tuning.identify.heat_run_log] written as a bench records
it: a capture file as an instrument or firmware tool writes one, with the signals a drive has.

**The signals** (from the heat run's columns, integrated by SciPy, not by this project's engine):

- the phase duties ``d_a, d_b, d_c`` of a min-max (SVPWM-equivalent) modulator on a 600 V DC link, from
  the commanded alpha-beta voltages (the reference loop's current steps ask for up to 240 V), in percent;
- the DC-link voltage, V;
- the two current sensors as read: phase a in A, phase b in mA;
- the quadrature count of an incremental encoder with ``ENCODER_LINES`` lines, from the measured angle
  (the encoder's index turned by the heat run's encoder offset), in a counter that reloads once per
  revolution (``4 x lines`` counts), rounded down to whole counts;
- the electrical speed in r/min (erpm), and the winding temperature, degC;
- time in ms, the captures separated by the gaps between bursts.

**The files.** [`write_capture_csv`][tuning.identify.bench_capture.write_capture_csv]: semicolon separated,
an instrument's preamble of ``key;value`` lines, a blank line and a comment above the header, the units
in the column names (``Time [ms]``, ``Phase A [A]``, ``Ib/mA``, ``Duty A [%]``).
[`write_capture_mat`][tuning.identify.bench_capture.write_capture_mat]: the same columns as a MATLAB v7.3
file, one variable per column, in the CSV's units.
[`CAPTURE_CONFIG`][tuning.identify.bench_capture.CAPTURE_CONFIG] and
[`MAT_CONFIG`][tuning.identify.bench_capture.MAT_CONFIG] are the log configs that map their names.
"""

import math
from pathlib import Path

import numpy as np

from pmsmjax.io.logs import atomic_write
from pmsmjax.io.mat_files import write_mat_v73
from tuning.identify.heat_run_log import MOTOR
from tuning.identify.log_columns import segment_bounds

__all__ = [
    "ENCODER_LINES",
    "U_DC_V",
    "CAPTURE_CONFIG",
    "MAT_CONFIG",
    "capture_columns",
    "write_capture_csv",
    "write_capture_mat",
]

#: Lines per revolution of the capture's encoder.
ENCODER_LINES = 2500
#: DC-link voltage of the capture's modulator, V.
U_DC_V = 600.0
#: The log config of the capture files: the names the CSV's header and the MAT file's variables map to
#: (``Phase A [A]`` is given on the command line, ``--columns i_a="Phase A [A]"``; ``Time [ms]`` and the
#: unit suffixes need no entry).
CAPTURE_CONFIG = """[columns]
i_b = "Ib"
d_a = "Duty A"
d_b = "Duty B"
d_c = "Duty C"
U_dc = "Udc"
encoder_counts = "Encoder"
omega_m = "ERPM"
temperature_c = "Winding"

[units]
omega_m = "erpm"
"""


#: The log config of the MATLAB capture, whose variable names carry no units.
MAT_CONFIG = """[columns]
time = "Time_ms"
i_a = "Ia"
i_b = "Ib"
d_a = "Duty_A"
d_b = "Duty_B"
d_c = "Duty_C"
U_dc = "Udc"
encoder_counts = "Encoder"
omega_m = "ERPM"
temperature_c = "Winding"

[units]
time = "ms"
i_b = "mA"
d_a = "%"
d_b = "%"
d_c = "%"
omega_m = "erpm"
"""


def capture_columns(heat_run: dict) -> dict[str, np.ndarray]:
    """``{name in file: (N,) array}`` of the capture (module docstring) from the heat run's columns."""
    p = MOTOR["pole_pairs"]
    u_a = heat_run["u_alpha"]
    u_b = -0.5 * heat_run["u_alpha"] + 0.5 * math.sqrt(3.0) * heat_run["u_beta"]
    u = np.stack([u_a, u_b, -u_a - u_b])
    u = u - 0.5 * (u.max(axis=0) + u.min(axis=0))  # min-max zero sequence
    duties = 0.5 + u / U_DC_V
    per_rev = 4 * ENCODER_LINES
    bounds = segment_bounds(heat_run["time"])
    counts = []
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        # The mechanical angle within the electrical period of the capture's start (the count's revolution
        # is not in the log; any one gives the same electrical angle).
        mech = np.mod(np.unwrap(heat_run["theta_e"][a:b]), 2.0 * math.pi * p) / p
        counts.append(np.mod(np.floor(mech / (2.0 * math.pi) * per_rev), per_rev))
    return {
        "Time [ms]": 1e3 * heat_run["time"],
        "Phase A [A]": heat_run["i_a"],
        "Ib/mA": 1e3 * heat_run["i_b"],
        "Duty A [%]": 100.0 * duties[0],
        "Duty B [%]": 100.0 * duties[1],
        "Duty C [%]": 100.0 * duties[2],
        "Udc [V]": np.full(u_a.size, U_DC_V),
        "Encoder [counts]": np.concatenate(counts),
        "ERPM": heat_run["omega_m"] * p * 30.0 / math.pi,
        "Winding [degC]": heat_run["temperature_c"],
    }


def write_capture_csv(path, heat_run: dict) -> Path:
    """Write the capture as an instrument's semicolon CSV with a preamble (module docstring)."""
    cols = capture_columns(heat_run)
    table = np.stack(list(cols.values()), axis=1)
    preamble = (
        "Instrument;Bench logger\nSample rate;10000 Hz\nTrigger;re-armed every 30 s\n\n"
        "# capture of a heat run: four bursts\n"
    )

    def writer(f):
        f.write(preamble.encode() + (";".join(cols) + "\n").encode())
        np.savetxt(f, table, fmt="%.17g", delimiter=";")

    return atomic_write(path, writer)


def write_capture_mat(path, heat_run: dict) -> Path:
    """Write the capture as a MATLAB v7.3 file, one variable per column, named as the CSV's columns without
    their unit suffixes (a MATLAB name has no brackets): ``Time_ms`` in ms, ``Ia``, ``Ib`` in mA, ``Duty_A``
    ... in percent (the log config's units say so), ``Udc``, ``Encoder``, ``ERPM``, ``Winding``."""
    cols = capture_columns(heat_run)
    names = {
        "Time [ms]": "Time_ms", "Phase A [A]": "Ia", "Ib/mA": "Ib", "Duty A [%]": "Duty_A",
        "Duty B [%]": "Duty_B", "Duty C [%]": "Duty_C", "Udc [V]": "Udc", "Encoder [counts]": "Encoder",
        "ERPM": "ERPM", "Winding [degC]": "Winding",
    }  # fmt: skip
    return write_mat_v73(path, {names[k]: v for k, v in cols.items()})
