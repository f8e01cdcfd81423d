"""``--motor`` as a drive file on every command that runs a drive (pmsmjax/cli/drive_flags.py).

The book default is checked against runs made directly through the presets API; the example drives
against their own files' ratings; the overrides against what the built drive holds.
"""

import json
import math

import numpy as np
import pytest

from pmsmjax.cli import build_parser, main
from pmsmjax.io.drive_files import PRESET_FOLDER, drive_spec

EXAMPLE_DRIVES = ("servo-400w", "industrial-5k6w", "outer-rotor-24v")


def run_json(argv, name):
    assert main([str(a) for a in argv]) == 0
    out = argv[argv.index("--out") + 1]
    return json.loads((out / name).read_text())


def test_demo_book_default_is_the_presets_run(tmp_path):
    """``demo`` with no drive flags writes the metrics of the book drive and scenario built by the presets."""
    from pmsmjax import presets
    from pmsmjax.analysis.speed_step_summary import speed_step_summary
    from pmsmjax.simulate import simulate

    summary = run_json(["demo", "--no-figures", "--out", tmp_path / "o"], "summary.json")
    trace = simulate(presets.book_drive(), presets.book_scenario()).to_numpy()
    expected = speed_step_summary(trace, load_time_s=0.2, current_limit_a=15.0)
    assert summary["metrics"] == pytest.approx(expected, rel=0, abs=0)
    assert summary["scenario"] == {
        "speed_rpm": 1000.0,
        "load_nm": 10.0,
        "load_time_s": 0.2,
        "duration_s": 0.4,
    }
    assert summary["drive"]["u_dc_v"] == 311.0 and summary["drive_file"]["source"] == "book"


@pytest.mark.slow
@pytest.mark.parametrize("name", EXAMPLE_DRIVES)
def test_demo_example_drive_reaches_rated_speed_within_its_current(tmp_path, name):
    """Each example drive, with no operating-point flags, holds its rated speed under 0.8 x rated torque
    within 0.5 % and never exceeds its file's peak current."""
    spec = drive_spec(name)
    summary = run_json(["demo", "--motor", name, "--no-figures", "--out", tmp_path / "o"], "summary.json")
    m, rated = summary["metrics"], spec.ratings["rated_speed_rpm"]
    assert summary["scenario"]["load_nm"] == pytest.approx(0.8 * spec.ratings["rated_torque_nm"])
    assert abs(m["final_speed_rpm"] - rated) <= 0.005 * rated
    assert m["peak_phase_current_a"] <= spec.ratings["max_current_a"] * (1 + 1e-6)
    assert summary["drive"]["u_dc_v"] == spec.u_dc_v
    assert summary["drive"]["Ts_s"] == pytest.approx(1.0 / spec.inverter["switching_frequency_hz"])
    assert summary["operating_point"]["flags"] == []
    dead = summary["drive"]["bridge_dead_time"]  # the averaged bridge models the file's dead time
    assert (
        dead["dead_time_s"] == spec.inverter["dead_time_s"] > 0 and dead["modelled"] and dead["compensated"]
    )


def test_raised_dc_link_admits_a_refused_speed(tmp_path, capsys):
    """8000 r/min is beyond 3x the book drive's no-load top speed (U_dc / sqrt 3 / (p psi_f)); the refusal
    names both knobs, and the same request on a drive file with a 1000 V DC link passes the precheck."""
    from pmsmjax.cli.demo import precheck

    top_311 = 311.0 / math.sqrt(3) / (4 * 0.1827) * 30 / math.pi
    assert 3 * top_311 < 8000 < 3 * top_311 * 1000 / 311
    out = tmp_path / "o"
    assert main(["demo", "--speed-rpm", "8000", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--u-dc" in err and "[inverter] u_dc_v" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()
    raised = tmp_path / "raised.toml"
    raised.write_text((PRESET_FOLDER / "book.toml").read_text().replace("u_dc_v = 311.0", "u_dc_v = 1000.0"))
    args = build_parser().parse_args(
        ["demo", "--motor", str(raised), "--speed-rpm", "8000", "--out", str(out)]
    )
    assert precheck(args).u_dc_v == 1000.0
    args = build_parser().parse_args(["demo", "--u-dc", "1000", "--speed-rpm", "8000", "--out", str(out)])
    assert precheck(args).u_dc_v == 1000.0


def test_overrides_reach_the_drive(tmp_path):
    short = ["--duration-s", "0.02", "--load-time-s", "0.01", "--no-figures"]
    argv = ["demo", "--u-dc", "400", "--current-limit", "12", *short, "--out", tmp_path / "o"]
    summary = run_json(argv, "summary.json")
    assert summary["drive"]["u_dc_v"] == 400.0 and summary["drive"]["current_limit_a"] == 12.0
    assert summary["drive_file"]["inverter"]["u_dc_v"] == 400.0
    assert summary["drive_file"]["ratings"]["max_current_a"] == 12.0


def test_six_phase_demo_uses_the_files_dc_link(tmp_path):
    drive_file = tmp_path / "six.toml"
    text = (PRESET_FOLDER / "six_phase_book.toml").read_text()
    drive_file.write_text(text.replace("u_dc_v = 311.0", "u_dc_v = 400.0"))
    argv = ["demo", "--machine", "six-phase", "--motor", drive_file, "--duration-s", "0.02"]
    summary = run_json(
        [*argv, "--load-time-s", "0.01", "--no-figures", "--out", tmp_path / "o"], "summary.json"
    )
    assert summary["drive"]["u_dc_v"] == 400.0
    assert summary["operating_point"]["voltage_limit_v"] == pytest.approx(400.0 / math.sqrt(3))


@pytest.mark.slow
def test_compare_book_default_is_the_presets_comparison(tmp_path):
    from pmsmjax import presets
    from pmsmjax.jobs.control_comparison import ControllerCompareSettings, compare_controllers

    run = ["--duration-s", "0.25", "--load-time-s", "0.15"]
    report = run_json(
        ["compare", "--control", "pi", *run, "--no-figures", "--out", tmp_path / "o"], "compare.json"
    )
    settings = ControllerCompareSettings(duration_s=0.25, load_time_s=0.15)
    expected = compare_controllers(["pi"], presets.book_motor(), settings)["controllers"]["pi"]
    got = report["controllers"]["pi"]
    for key in ("rise_time_s", "dip_rpm", "itae", "current_thd_pct", "torque_ripple_nm", "final_speed_rpm"):
        assert got[key] == expected[key], key


@pytest.mark.slow
def test_compare_runs_on_an_example_drive(tmp_path):
    spec = drive_spec("servo-400w")
    argv = ["compare", "--motor", "servo-400w", "--control", "pi", "--no-figures", "--out", tmp_path / "o"]
    report = run_json(argv, "compare.json")
    pi = report["controllers"]["pi"]
    assert report["drive_file"]["source"] == "servo-400w"
    assert pi["control_period_s"] == pytest.approx(spec.Ts) and pi["current_limit_a"] == 36.0
    assert abs(pi["final_speed_rpm"] - 3000.0) <= 0.005 * 3000.0
    assert pi["switching_frequency_hz"] == pytest.approx(20e3, rel=0.02)


@pytest.mark.slow
def test_pwm_compare_book_default_and_an_example_drive(tmp_path):
    """The book default equals the study run on its own default drive; on the servo file the inverter's
    48 V and 20 kHz set the linear limit and the analysis period."""
    from pmsmjax.jobs.pwm_comparison import CompareSettings, compare

    small = ["--modulators", "svpwm", "--settle-cycles", "1", "--window-cycles", "1", "--no-figures"]
    book = run_json(["pwm-compare", *small, "--out", tmp_path / "b"], "pwm.json")
    settings = CompareSettings(settle_cycles=1, window_cycles=1, modulators=("svpwm",), dead_time_s=2e-6)
    expected = compare(settings)["entries"]
    for name, entry in expected.items():
        for key, value in entry.items():
            if isinstance(value, float):
                assert book["entries"][name][key] == value, (name, key)
    servo = run_json(["pwm-compare", "--motor", "servo-400w", *small, "--out", tmp_path / "s"], "pwm.json")
    assert servo["settings"]["u_dc_v"] == 48.0 and servo["settings"]["Ts_s"] == pytest.approx(5e-5)
    assert servo["entries"]["svpwm"]["linear_limit_v"] == pytest.approx(48.0 / math.sqrt(3))
    assert servo["settings"]["dead_time_s"] == pytest.approx(5e-7)  # the file's dead time
    assert np.isfinite(servo["entries"]["svpwm_switching_deadtime"]["current_thd_pct"])
