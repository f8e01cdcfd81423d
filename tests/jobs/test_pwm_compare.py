"""``pmsmjax pwm-compare`` at a small size: the report's structure and the invariants it must obey.

- Inside the linear range every modulator gives the averaged bridge the same period-average voltage, so
  the averaged entries must be identical across modulators (to rounding).
- All variants run at the same operating point: equal fundamental phase voltage (closed loop), and the
  line-voltage fundamental is sqrt3 times the phase one (balanced).
- Linear limits and DC-bus utilisation are the book's: U_dc/2, U_dc/sqrt3, ratio 2/sqrt3.
- Physics that must show: the switching bridge's current ripple dominates the averaged bridge's THD, and a
  dead time adds distortion.
"""

import json

import numpy as np
import pytest

from pmsmjax.cli import main

S3 = np.sqrt(3.0)
KEYS = (
    "linear_limit_v",
    "dc_bus_utilisation_vs_sinusoidal",
    "fundamental_phase_voltage_v",
    "fundamental_line_voltage_v",
    "fundamental_current_a",
    "voltage_thd_pct",
    "line_voltage_thd_pct",
    "current_thd_pct",
)


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    out = tmp_path_factory.mktemp("pwm")
    argv = ["pwm-compare", "--out", str(out), "--modulators", "sinusoidal", "svpwm"]
    assert main(argv + ["--settle-cycles", "1", "--window-cycles", "1"]) == 0
    return out, json.loads((out / "pwm.json").read_text())


@pytest.mark.slow
def test_report_has_every_variant_and_figure(report):
    out, data = report
    names = [m + s for m in ("sinusoidal", "svpwm") for s in ("", "_switching", "_switching_deadtime")]
    assert sorted(data["entries"]) == sorted(names)
    for name in names:
        entry = data["entries"][name]
        for key in KEYS:
            assert np.isfinite(entry[key]) and entry[key] > 0, (name, key)
    for f in ("waveforms.npz", "pwm_waveforms.png", "pwm_spectra.png", "pwm_thd.png"):
        assert (out / f).stat().st_size > 0
    assert data["settings"]["thd_max_frequency_hz"] == pytest.approx(40e3)


def test_linear_limits_and_bus_utilisation(report):
    e = report[1]["entries"]
    assert e["sinusoidal_switching"]["linear_limit_v"] == pytest.approx(311.0 / 2)
    assert e["svpwm_switching"]["linear_limit_v"] == pytest.approx(311.0 / S3)
    assert e["svpwm"]["dc_bus_utilisation_vs_sinusoidal"] == pytest.approx(2 / S3)
    assert e["sinusoidal"]["dc_bus_utilisation_vs_sinusoidal"] == 1.0


def test_averaged_entries_do_not_depend_on_the_modulator(report):
    e = report[1]["entries"]
    for key in ("fundamental_phase_voltage_v", "voltage_thd_pct", "current_thd_pct"):
        assert e["sinusoidal"][key] == pytest.approx(e["svpwm"][key], rel=1e-4), key


def test_variants_run_at_equal_fundamental_voltage(report):
    e = report[1]["entries"]
    ideal = np.array([v["fundamental_phase_voltage_v"] for k, v in e.items() if "deadtime" not in k])
    assert np.ptp(ideal) < 1e-3 * ideal.mean()
    # with dead time the current loop restores the fundamental, after a transient of its own
    for k, v in e.items():
        assert v["fundamental_phase_voltage_v"] == pytest.approx(ideal.mean(), rel=0.01), k
    for v in e.values():
        assert v["fundamental_line_voltage_v"] == pytest.approx(
            S3 * v["fundamental_phase_voltage_v"], rel=1e-6
        )


def test_ripple_and_dead_time_show_in_the_current_thd(report):
    e = report[1]["entries"]
    for m in ("sinusoidal", "svpwm"):
        assert e[m + "_switching"]["current_thd_pct"] > 10 * e[m]["current_thd_pct"]
        assert e[m + "_switching_deadtime"]["current_thd_pct"] > 1.2 * e[m + "_switching"]["current_thd_pct"]


def test_bad_speed_is_rejected_before_compiling(capsys):
    assert main(["pwm-compare", "--out", "unused", "--speed-rpm", "1234"]) == 2
    assert "whole" in capsys.readouterr().err


def test_help(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["pwm-compare", "--help"])
    assert exit_info.value.code == 0
    assert "pwm.json" in capsys.readouterr().out
