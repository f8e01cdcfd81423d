"""Every control method through the same commands: the registry, ``demo --control``, ``compare`` and
``tune --control`` (one engine for every method of the book).

Independent references: the demo and the comparison compute their figures by different code paths from
separate runs (they must agree on the same drive); the switching frequency of carrier PWM is its carrier
frequency by construction of the modulator; the SMC is tuned on its tanh surrogate and the exact sign law
is re-evaluated (both reported).
"""

import json

import numpy as np
import pytest

from pmsmjax import ParameterError
from pmsmjax.cli import main
from pmsmjax.controllers import FOC, HysteresisCurrentControl, ProportionalResonant, SlidingModeSpeed
from pmsmjax.presets.control_methods import CONTROLS, control_drive
from tuning.parameters import read_gains_toml

SHORT = ["--duration-s", "0.3", "--load-time-s", "0.15", "--speed-rpm", "1000", "--load-nm", "5"]


def test_registry_builds_each_method_and_refuses_what_does_not_apply():
    kinds = {
        "pi": (FOC, "voltage"),
        "smc": (FOC, "voltage"),
        "pr": (FOC, "voltage"),
        "hysteresis": (HysteresisCurrentControl, "switches"),
    }
    assert set(CONTROLS) >= set(kinds)
    for name, (cls, command) in kinds.items():
        drive = control_drive(name)
        assert isinstance(drive.controller, cls) and drive.controller.command_kind == command
    assert isinstance(control_drive("smc").controller.speed, SlidingModeSpeed)
    assert isinstance(control_drive("pr").controller.current, ProportionalResonant)
    assert control_drive("hysteresis").modulator is None
    with pytest.raises(ParameterError, match="unknown control 'foo'"):
        control_drive("foo")
    with pytest.raises(ParameterError, match="band_a do not apply to control 'pi'"):
        control_drive("pi", band_a=1.0)


@pytest.mark.parametrize("control", ["smc", "pr", "hysteresis"])
def test_demo_runs_each_control(control, tmp_path):
    out = tmp_path / control
    assert main(["demo", "--control", control, "--out", str(out), "--no-figures", *SHORT]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["drive"]["control"] == control
    m = summary["metrics"]
    assert abs(m["final_speed_rpm"] - 1000.0) < 10.0
    assert m["current_limit_respected"] is True


def test_demo_refuses_a_flag_of_another_control_before_writing(tmp_path, capsys):
    out = tmp_path / "x"
    assert main(["demo", "--control", "pi", "--band-a", "1", "--out", str(out), *SHORT]) == 2
    assert "--band-a does not apply to --control pi" in capsys.readouterr().err
    assert not out.exists()
    assert main(["demo", "--control", "hysteresis", "--current-bandwidth", "900", "--out", str(out)]) == 2
    assert not out.exists()


def test_demo_with_field_weakening_runs_above_base_speed(tmp_path):
    """The i_d = 0 drive cannot pass about 2300 r/min at 311 V (tests/controllers/test_field_weakening.py);
    with
    --field-weakening the demo reaches 2500 r/min and holds it under 5 N m within the current limit."""
    out = tmp_path / "fw"
    args = ["--speed-rpm", "2500", "--load-nm", "5", "--load-time-s", "0.3", "--duration-s", "0.5"]
    assert main(["demo", "--field-weakening", "--out", str(out), "--no-figures", *args]) == 0
    m = json.loads((out / "summary.json").read_text())["metrics"]
    assert abs(m["final_speed_rpm"] - 2500.0) < 25.0
    assert m["peak_phase_current_a"] <= 15.0 * 1.001


@pytest.fixture(scope="module")
def compared(tmp_path_factory):
    out = tmp_path_factory.mktemp("compare")
    assert main(["compare", "--out", str(out), *SHORT]) == 0
    return out, json.loads((out / "compare.json").read_text())


@pytest.mark.slow
def test_compare_writes_every_controller_with_its_figures(compared):
    out, data = compared
    keys = (
        "rise_time_s",
        "overshoot_pct",
        "dip_rpm",
        "recovery_time_s",
        "itae",
        "peak_current_a",
        "current_thd_pct",
        "switching_frequency_hz",
        "torque_ripple_nm",
    )
    assert list(data["controllers"]) == ["pi", "smc", "pr", "hysteresis"]
    for name, entry in data["controllers"].items():
        for key in keys:
            assert np.isfinite(entry[key]), (name, key)
        assert abs(entry["final_speed_rpm"] - 1000.0) < 10.0, name
        assert entry["peak_current_a"] <= 15.0 * 1.02, name
        # Under 5 N m (plus friction) the mean torque in the window balances the load.
        assert entry["mean_torque_nm"] == pytest.approx(5.0 + 0.008 * 104.72, rel=0.02), name
    # SVPWM inside its linear range switches every leg once per period: the carrier frequency exactly.
    for name in ("pi", "smc", "pr"):
        assert data["controllers"][name]["switching_frequency_hz"] == pytest.approx(1e4, rel=1e-12)
    # The hysteresis band (0.5 A at 10 us) switches near the same frequency
    # (tests/controllers/test_hysteresis.py).
    assert 5e3 < data["controllers"]["hysteresis"]["switching_frequency_hz"] < 20e3
    for name in ("compare_speed.png", "compare_ripple.png"):
        assert (out / name).read_bytes()[:4] == b"\x89PNG"


def test_compare_and_demo_agree_on_the_same_drive(compared, tmp_path):
    """``compare --bridge averaged`` and ``demo`` are separate runs and separate code paths."""
    out = tmp_path / "avg"
    assert (
        main(
            ["compare", "--control", "pi", "--bridge", "averaged", "--out", str(out), "--no-figures", *SHORT]
        )
        == 0
    )
    entry = json.loads((out / "compare.json").read_text())["controllers"]["pi"]
    assert main(["demo", "--out", str(tmp_path / "demo"), "--no-figures", *SHORT]) == 0
    m = json.loads((tmp_path / "demo" / "summary.json").read_text())["metrics"]
    assert entry["rise_time_s"] == pytest.approx(m["rise_time_s"], rel=1e-9)
    assert entry["dip_rpm"] == pytest.approx(m["speed_dip_rpm"], rel=1e-9)
    assert entry["itae"] == pytest.approx(m["itae_rad_s"], rel=1e-9)


def test_compare_refuses_bad_input_before_any_work(tmp_path, capsys):
    assert main(["compare", "--control", "pi,foo", "--out", str(tmp_path / "a")]) == 2
    assert "unknown foo" in capsys.readouterr().err  # no Python list repr
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert main(["compare", "--control", "pi", "--out", str(blocker / "sub")]) == 2
    assert "is an existing file" in capsys.readouterr().err
    assert main(["compare", "--control", "pi", "--speed-rpm", "700", "--out", str(tmp_path / "b")]) == 2
    assert "not a whole" in capsys.readouterr().err
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


@pytest.mark.slow
def test_tune_smc_tunes_the_surrogate_and_reports_the_exact_law(tmp_path):
    out = tmp_path / "tune"
    args = ["tune", "--control", "smc", "--out", str(out), "--train", "2", "--heldout", "2"]
    assert main([*args, "--iterations", "2", "--duration-s", "0.05", "0.06", "--no-progress"]) == 0
    data = json.loads((out / "result.json").read_text())
    assert data["control"] == "smc"
    assert data["surrogate"]["options"] == {"switching": "tanh"}
    gains = read_gains_toml(out / "gains.toml")
    for name in (
        "controller.speed.c",
        "controller.speed.eps",
        "controller.speed.q",
        "controller.current.kp_q",
    ):
        assert name in gains
    for when in ("after", "after_surrogate"):
        assert np.isfinite(data["heldout"][when]["itae"])
    # The exact sign law and the tanh surrogate are different models: their figures differ.
    assert data["heldout"]["after"]["itae"] != data["heldout"]["after_surrogate"]["itae"]


def test_tune_refuses_a_control_it_cannot_tune(tmp_path, capsys):
    with pytest.raises(SystemExit):
        main(["tune", "--control", "hysteresis", "--out", str(tmp_path / "t")])
    assert "invalid choice" in capsys.readouterr().err


@pytest.mark.slow
def test_controller_benchmark_smoke():
    """benchmarks/bench_controllers.py at quick sizes: every control timed, ratios consistent."""
    from benchmarks import bench_controllers

    r = bench_controllers.run(quick=True)
    assert set(bench_controllers.REQUIRED_KEYS) <= set(r)
    assert set(r["controls"]) == set(CONTROLS)
    assert r["controls"]["pi"]["per_period_vs_pi"] == 1.0
    for c in r["controls"].values():
        assert c["run_s"] > 0 and np.isfinite(c["us_per_period"])
        # per simulated second = per period x periods per second, both relative to PI
        ratio = c["per_period_vs_pi"] * (r["controls"]["pi"]["control_period_s"] / c["control_period_s"])
        assert c["per_simulated_s_vs_pi"] == pytest.approx(ratio, rel=1e-9)
    assert "control methods on the book scenario" in bench_controllers.format_table(r)
