"""The five-phase drive through the commands and workflows: ``pmsmjax demo --machine five-phase``,
``pmsmjax pwm-compare --phases 5``, ``pmsmjax tune --machine five-phase`` and the Monte Carlo study with
``machine = "five-phase"``; bad flag combinations refused before anything is written.

Independent references: the demo's summary against a direct ``simulate`` of the same preset; the x-y
harmonic currents of large-vector SVPWM against the x-y voltage it applies divided by the x-y impedance
``|R + j h w_e L_ls|`` (computed here); the Monte Carlo kernel's peak current against the full trace.
"""

import json

import numpy as np
import pytest

from pmsmjax import simulate
from pmsmjax.analysis.speed_step_summary import speed_step_summary
from pmsmjax.cli import main
from pmsmjax.presets.five_phase import five_phase_drive, five_phase_motor
from pmsmjax.presets.three_phase import book_scenario
from tuning.montecarlo import run_study
from tuning.montecarlo.kernel import run_metrics
from tuning.montecarlo.study import Study

SHORT = ["--duration-s", "0.12", "--load-time-s", "0.08", "--speed-rpm", "500", "--load-nm", "5"]


@pytest.mark.parametrize("control, pwm", [("vsd", None), ("conventional", "large-vector"), ("pr", "carrier")])
def test_demo_five_phase(control, pwm, tmp_path):
    out = tmp_path / control
    args = ["demo", "--machine", "five-phase", "--control", control, "--out", str(out), *SHORT]
    args += ["--pwm", pwm] if pwm else []
    args += [] if control == "vsd" else ["--no-figures"]
    assert main(args) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["drive"]["machine"] == "five-phase" and summary["drive"]["control"] == control
    assert summary["drive"]["pwm"] == (pwm or "near-four-vector")
    trace = simulate(
        five_phase_drive(control=control, pwm=pwm or "near-four-vector"),
        book_scenario(500.0, 5.0, 0.08, 0.12),
    )
    direct = speed_step_summary(trace, load_time_s=0.08, current_limit_a=15.0)
    assert summary["metrics"]["final_speed_rpm"] == pytest.approx(direct["final_speed_rpm"], rel=1e-9)
    header = (out / "trace.csv").read_text().splitlines()[0].split(",")
    assert {"i_a", "i_D", "i_E", "duty_E", "i_d"} <= set(header)
    assert set(header) == set(summary["trace_columns"])  # every column's unit is listed
    if pwm == "large-vector":  # x-y left to the modulator: 3rd/7th currents flow
        assert summary["metrics"]["xy_current_peak_a"] > 1.0
    else:
        assert summary["metrics"]["xy_current_peak_a"] < 1e-6
    if control == "vsd":
        assert (out / "currents_xy.png").stat().st_size > 0
    # The operating-point check uses the five-phase torque factor: 5 N m at 500 r/min is reachable.
    assert not summary["operating_point"]["flags"] or all(
        "more than the" not in f["cause"] for f in summary["operating_point"]["flags"]
    )


@pytest.mark.parametrize(
    "args, message",
    [
        (["--machine", "five-phase", "--control", "smc"], "three-phase control"),
        (["--machine", "five-phase", "--control", "double-dq"], "another machine's control"),
        (["--machine", "five-phase", "--pwm", "four-vector"], "does not drive the five-phase machine"),
        (["--machine", "five-phase", "--frame", "double-dq"], "five-phase frames: dq, vsd, natural"),
        (["--machine", "five-phase", "--band-a", "1"], "--band-a does not apply to --machine five-phase"),
    ],
)
def test_demo_refuses_mismatched_flags_before_writing(args, message, tmp_path, capsys):
    out = tmp_path / "x"
    assert main(["demo", *args, "--out", str(out), *SHORT]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_pwm_compare_five_phases(tmp_path):
    out = tmp_path / "pwm5"
    args = ["pwm-compare", "--phases", "5", "--out", str(out), "--settle-cycles", "1", "--window-cycles", "1"]
    assert main([*args, "--modulators", "near-four-vector", "large-vector", "--no-figures"]) == 0
    report = json.loads((out / "pwm.json").read_text())
    assert report["settings"]["phases"] == 5
    e = report["entries"]
    assert set(e) == {
        "near-four-vector",
        "near-four-vector_switching",
        "large-vector",
        "large-vector_switching",
    }
    nfv, lv = e["near-four-vector_switching"], e["large-vector_switching"]
    assert nfv["linear_limit_v"] == pytest.approx(311.0 / (2 * np.cos(np.pi / 10)))
    assert abs(nfv["fundamental_phase_voltage_v"] - lv["fundamental_phase_voltage_v"]) < 0.5
    assert nfv["xy_average_voltage_rms_v"] < 1e-9 and lv["xy_average_voltage_rms_v"] > 5.0
    # Large-vector SVPWM leaves a 3rd/7th harmonic x-y voltage; through the leakage it drives amperes, the
    # near-four-vector method none. The 3rd lives in x-y: the phase harmonic equals the x-y current's.
    assert lv["harmonic_3_current_a"] > 5.0 and lv["harmonic_3_current_a"] > 100 * nfv["harmonic_3_current_a"]
    assert lv["harmonic_3_current_a"] == pytest.approx(lv["harmonic_3_xy_current_a"], rel=0.02)
    assert lv["current_thd_pct"] > 10 * nfv["current_thd_pct"]


def test_large_vector_xy_current_is_its_xy_voltage_over_the_leakage_impedance():
    from pmsmjax.studies.pwm_comparison_multiphase import SixPhaseCompareSettings, compare_six_phase

    settings = SixPhaseCompareSettings(
        phases=5,
        modulators=("large-vector",),
        bridges=("averaged",),
        settle_cycles=2,
        window_cycles=1,
        samples_per_period=16,
        thd_max_carriers=2.0,
    )
    result = compare_six_phase(settings)
    wave = result["waves"]["large-vector"]
    motor = five_phase_motor()
    w_e = 4 * 1000.0 * np.pi / 30
    # Fourier component of order h of the period-average x-y voltage (complex, stationary frame).
    u = wave["u_vsd_period"][:, 2] + 1j * wave["u_vsd_period"][:, 3]
    i = wave["i_vsd"][:, 2] + 1j * wave["i_vsd"][:, 3]
    t_u = (np.arange(len(u)) + 0.5) * 1e-4
    t_i = wave["t_i"]
    checked = []
    for h in (3, -3, 7, -7):
        u_h = np.mean(u * np.exp(-1j * h * w_e * t_u))
        i_h = np.mean(i * np.exp(-1j * h * w_e * t_i))
        z = float(motor.R) + 1j * h * w_e * float(motor.L_ls)
        if abs(u_h) > 1.0:
            # Held voltage over a period: a half-period delay and a sinc factor, both known here.
            hold = np.sinc(h * w_e * 1e-4 / (2 * np.pi))
            assert abs(i_h) == pytest.approx(abs(u_h) * hold / abs(z), rel=0.005), h
            checked.append(h)
    # The 3rd rotates forwards and the 7th backwards in x-y (15 V and 2.6 V on the preset).
    assert checked == [3, -7]


def test_tune_five_phase(tmp_path):
    out = tmp_path / "tune5"
    args = ["tune", "--machine", "five-phase", "--control", "vsd", "--out", str(out), "--train", "2"]
    assert (
        main([*args, "--heldout", "2", "--iterations", "2", "--duration-s", "0.05", "0.06", "--no-progress"])
        == 0
    )
    data = json.loads((out / "result.json").read_text())
    assert data["machine"] == "five-phase" and data["control"] == "vsd"
    assert data["train"]["after"]["cost"] <= data["train"]["before"]["cost"] * (1 + 1e-9)


def test_montecarlo_five_phase(tmp_path):
    study = Study(
        n=4,
        machine="five-phase",
        control="vsd",
        duration_s=0.06,
        load_time_s=0.03,
        speed_rpm=600.0,
        load_nm=3.0,
        decimate=20,
        chunk_size=4,
        sensitivity_runs=2,
        parameters={"motor.R": {"tolerance": 0.2}, "motor.L_ls": {"tolerance": 0.3}},
    )
    summary = run_study(study, tmp_path / "mc", progress=False, figures=False)
    assert summary["n_runs"] == 4
    assert summary["failures"]["unstable"]["count"] == 0
    assert np.isfinite(summary["metrics"]["itae"]["p50"]) and summary["metrics"]["itae"]["std"] > 0
    drive = five_phase_drive(control="vsd")
    scenario = book_scenario(600.0, 3.0, 0.03, 0.06)
    m, _ = run_metrics(drive, scenario, 0.03, decimate=20)
    assert float(m["peak_current_a"]) == pytest.approx(float(np.max(np.abs(simulate(drive, scenario).i_abc))))
