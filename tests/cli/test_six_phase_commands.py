"""The six-phase drive through the commands and workflows: ``pmsmjax demo --machine six-phase``,
``pmsmjax pwm-compare --phases 6``, ``pmsmjax tune --machine six-phase`` and ``pmsmjax montecarlo
--machine six-phase``; bad flag combinations refused before anything is written.

Independent references: the demo's summary against a direct ``simulate`` of the same preset; the motor
file against the preset it documents; the Monte Carlo kernel's peak current against the full trace.

The figures come from pmsmjax/plotting/six_phase.py.
"""

import json

import numpy as np
import pytest

from pmsmjax import simulate
from pmsmjax.analysis.speed_step_summary import speed_step_summary
from pmsmjax.cli import main
from pmsmjax.presets.six_phase import (
    SIX_PHASE_MOTOR_FILE,
    load_six_phase_motor,
    six_phase_drive,
    six_phase_motor,
)
from pmsmjax.presets.three_phase import book_scenario
from tuning.montecarlo import run_study
from tuning.montecarlo.kernel import run_metrics
from tuning.montecarlo.study import Study
from tuning.parameters import read_gains_toml

SHORT = ["--duration-s", "0.12", "--load-time-s", "0.08", "--speed-rpm", "500", "--load-nm", "5"]


@pytest.mark.parametrize(
    "control, pwm",
    [("double-dq", "decoupled"), ("pr", "double-zs"), ("vsd", None), ("conventional", "two-vector")],
)
def test_demo_six_phase(control, pwm, tmp_path):
    out = tmp_path / control
    args = ["demo", "--machine", "six-phase", "--control", control, "--out", str(out), *SHORT]
    args += ["--pwm", pwm] if pwm else []
    args += [] if control == "vsd" else ["--no-figures"]
    assert main(args) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["drive"]["machine"] == "six-phase" and summary["drive"]["control"] == control
    assert summary["drive"]["pwm"] == (pwm or "four-vector")
    trace = simulate(
        six_phase_drive(control=control, pwm=pwm or "four-vector"), book_scenario(500.0, 5.0, 0.08, 0.12)
    )
    direct = speed_step_summary(trace, load_time_s=0.08, current_limit_a=15.0)
    assert summary["metrics"]["final_speed_rpm"] == pytest.approx(direct["final_speed_rpm"], rel=1e-9)
    assert summary["metrics"]["peak_phase_current_a"] == pytest.approx(
        direct["peak_phase_current_a"], rel=1e-9
    )
    header = (out / "trace.csv").read_text().splitlines()[0].split(",")
    assert {"i_a", "i_u", "i_w", "duty_v"} <= set(header)
    assert set(header) == set(summary["trace_columns"])  # every column's unit is listed
    if pwm == "two-vector":  # z1-z2 left to the modulator: 5th/7th currents flow
        assert summary["metrics"]["z_current_peak_a"] > 1.0
    else:
        assert summary["metrics"]["z_current_peak_a"] < 1e-6
    if control == "vsd":
        assert (out / "currents_z.png").stat().st_size > 0 and (out / "overview.png").stat().st_size > 0


@pytest.mark.parametrize(
    "args, message",
    [
        (["--machine", "six-phase", "--control", "smc"], "three-phase control"),
        (["--machine", "six-phase", "--band-a", "1"], "--band-a does not apply to --machine six-phase"),
        (["--machine", "six-phase", "--frame", "abc"], "three-phase frame"),
        (["--pwm", "four-vector"], "--pwm applies to --machine six-phase only"),
        (["--control", "double-dq"], "needs --machine six-phase"),
        (["--frame", "natural"], "six-phase frame"),
    ],
)
def test_demo_refuses_mismatched_flags_before_writing(args, message, tmp_path, capsys):
    out = tmp_path / "x"
    assert main(["demo", *args, "--out", str(out), *SHORT]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_motor_file_is_the_documented_preset():
    from_file, preset = load_six_phase_motor(SIX_PHASE_MOTOR_FILE), six_phase_motor()
    for f in ("R", "L_d", "L_q", "psi_f", "L_ls", "J", "B"):
        assert float(getattr(from_file, f)) == pytest.approx(float(getattr(preset, f)), rel=1e-12)
    assert from_file.pole_pairs == 4 and from_file.n_phases == 6
    assert float(preset.torque_constant) == pytest.approx(1.5 * 4 * 0.1827, rel=1e-12)  # the book motor's


def test_pwm_compare_six_phases_writes_its_table_and_figures(tmp_path):
    out = tmp_path / "pwm6"
    args = ["pwm-compare", "--phases", "6", "--out", str(out), "--settle-cycles", "1", "--window-cycles", "1"]
    assert main([*args, "--modulators", "four-vector", "two-vector"]) == 0
    report = json.loads((out / "pwm.json").read_text())
    assert set(report["entries"]) == {
        "four-vector",
        "four-vector_switching",
        "two-vector",
        "two-vector_switching",
    }
    for e in report["entries"].values():
        for key in (
            "linear_limit_v",
            "fundamental_phase_voltage_v",
            "z_average_voltage_rms_v",
            "current_thd_pct",
            "harmonic_5_current_a",
            "harmonic_7_current_a",
        ):
            assert np.isfinite(e[key]), key
    assert report["entries"]["two-vector"]["z_average_voltage_rms_v"] > 1.0
    assert report["entries"]["four-vector"]["z_average_voltage_rms_v"] < 1e-9
    for name in ("pwm6_vectors.png", "pwm6_trajectories.png", "pwm6_harmonics.png", "waveforms.npz"):
        assert (out / name).stat().st_size > 0


def test_tune_six_phase(tmp_path):
    out = tmp_path / "tune6"
    args = ["tune", "--machine", "six-phase", "--control", "double-dq", "--out", str(out), "--train", "2"]
    assert (
        main([*args, "--heldout", "2", "--iterations", "2", "--duration-s", "0.05", "0.06", "--no-progress"])
        == 0
    )
    data = json.loads((out / "result.json").read_text())
    assert data["machine"] == "six-phase" and data["control"] == "double-dq"
    gains = read_gains_toml(out / "gains.toml")
    for name in ("controller.speed.kp", "controller.current.kp_q", "controller.current.kc_d"):
        assert name in gains
    assert data["train"]["after"]["cost"] <= data["train"]["before"]["cost"] * (1 + 1e-9)
    for part in ("train", "heldout"):
        assert np.isfinite(data[part]["after"]["itae"])


def test_montecarlo_six_phase(tmp_path):
    study = Study(
        n=4,
        machine="six-phase",
        control="vsd",
        duration_s=0.06,
        load_time_s=0.03,
        speed_rpm=600.0,
        load_nm=3.0,
        decimate=20,
        chunk_size=4,
        sensitivity_runs=2,
        parameters={
            "motor.R": {"tolerance": 0.2},
            "motor.L_ls": {"tolerance": 0.3},
            "controller.current.z.kp": {"tolerance": 0.3},
        },
    )
    summary = run_study(study, tmp_path / "mc", progress=False, figures=False)
    # 60 ms is too short to settle (a tracking "failure" by the 10 r/min rule, as for three phases); no run
    # is unstable or over the current limit, and the sampled plants differ.
    assert summary["n_runs"] == 4
    assert (
        summary["failures"]["unstable"]["count"] == 0 and summary["failures"]["current_limit"]["count"] == 0
    )
    assert np.isfinite(summary["metrics"]["itae"]["p50"]) and summary["metrics"]["itae"]["std"] > 0
    # The kernel's peak phase current is the six phases' largest sample of the full trace.
    drive = six_phase_drive(control="vsd")
    scenario = book_scenario(600.0, 3.0, 0.03, 0.06)
    m, _ = run_metrics(drive, scenario, 0.03, decimate=20)
    assert float(m["peak_current_a"]) == pytest.approx(float(np.max(np.abs(simulate(drive, scenario).i_abc))))
    with pytest.raises(Exception, match="pwm applies to machine = 'six-phase' only"):
        Study(pwm="four-vector")
