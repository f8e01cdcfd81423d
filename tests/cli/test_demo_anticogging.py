"""``pmsmjax demo --anticogging FILE``: the table ``tune --anticogging`` writes, loaded back into the FOC."""

from pathlib import Path

import numpy as np

import pmsmjax.presets
from pmsmjax.cli import main
from pmsmjax.io.anticogging_files import write_anticogging_csv
from pmsmjax.io.logs import read_log

MOTORS_DIR = Path(pmsmjax.presets.__file__).resolve().parent / "motors"

COGGING = ((6, 0.045, 0.3), (12, 0.018, -0.8))
RUN = ["--no-figures", "--duration-s", "0.3", "--load-time-s", "0.25", "--speed-rpm", "60", "--load-nm", "0"]


def _drive(tmp_path):
    text = (MOTORS_DIR / "servo_400w_48v.toml").read_text()
    path = tmp_path / "drive.toml"
    path.write_text(text + f"\n[harmonics]\ncogging = {[list(r) for r in COGGING]}\n")
    return path


def _ripple_rad_s(out) -> float:
    trace = read_log(out / "trace.csv", ("time", "omega_m"))
    return float(np.std(trace["omega_m"][trace["time"] > 0.1]))


def test_demo_loads_the_anticogging_table(tmp_path):
    """The table that cancels the file's cogging (``-T_cog / k_t`` over 128 bins) takes the speed ripple at
    60 r/min from 0.17 to 0.008 rad/s (measured)."""
    drive = _drive(tmp_path)
    theta = 2 * np.pi * np.arange(128) / 128
    k_t = 1.5 * 4 * 0.0176
    iq = -sum(c * np.sin(n * theta + phi) for n, c, phi in COGGING) / k_t
    table = write_anticogging_csv(tmp_path / "anticogging.csv", iq)
    assert main(["demo", "--motor", str(drive), "--out", str(tmp_path / "a"), *RUN]) == 0
    argv = ["demo", "--motor", str(drive), "--out", str(tmp_path / "b"), "--anticogging", str(table), *RUN]
    assert main(argv) == 0
    assert _ripple_rad_s(tmp_path / "b") < 0.1 * _ripple_rad_s(tmp_path / "a")


def test_a_missing_table_is_refused_in_one_line(tmp_path, capsys):
    argv = ["demo", "--motor", str(_drive(tmp_path)), "--out", str(tmp_path / "a"), "--anticogging",
            str(tmp_path / "none.csv"), *RUN]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "does not exist" in err and "\n" not in err
