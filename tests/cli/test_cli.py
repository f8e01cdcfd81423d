"""The pmsmjax command: demo outputs, help texts, errors before any file is written."""

import argparse
import csv
import json
import subprocess
import sys

import numpy as np
import pytest

from pmsmjax.cli import build_parser, main

SHORT_DEMO = ["--duration-s", "0.3", "--load-time-s", "0.15", "--speed-rpm", "600", "--load-nm", "4"]


def _subcommands() -> list[str]:
    """Every subcommand the parser registers (so a new one is covered without editing this test)."""
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return sorted(sub.choices)


def test_subcommand_list_is_complete():
    expected = {
        "demo",
        "simulate",
        "replay",
        "bench",
        "tune",
        "pwm-compare",
        "compare",
        "identify",
        "montecarlo",
        "observe",
        "export",
    }
    assert set(_subcommands()) == expected


@pytest.mark.parametrize("command", _subcommands())
def test_every_subcommand_has_help(command, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main([command, "--help"])
    assert exit_info.value.code == 0
    assert "--out" in capsys.readouterr().out or command == "bench"


def test_module_entry_point_runs():
    result = subprocess.run(
        [sys.executable, "-m", "pmsmjax", "--help"], capture_output=True, text=True, check=False
    )
    assert result.returncode == 0 and "demo" in result.stdout and "replay" in result.stdout


def test_demo_writes_trace_summary_and_figures(tmp_path):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), *SHORT_DEMO]) == 0
    summary = json.loads((out / "summary.json").read_text())
    with open(out / "trace.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 3000  # 0.3 s at 10 kHz
    final_rpm = float(rows[-1]["speed_rpm"])
    # The summary is computed from the same trace that was written.
    assert summary["metrics"]["final_speed_rpm"] == pytest.approx(final_rpm, rel=1e-6)
    assert abs(final_rpm - 600.0) < 6.0
    for key in ("rise_time_s", "overshoot_pct", "settling_time_s", "speed_dip_rpm", "itae_rad_s"):
        assert key in summary["metrics"]
    assert summary["metrics"]["current_limit_respected"] is True
    for name in ("overview", "speed", "currents_dq", "currents_abc", "torque", "voltages_dq"):
        png = out / f"{name}.png"
        assert png.stat().st_size > 10_000 and png.read_bytes()[:4] == b"\x89PNG"
    assert not list(out.glob(".*tmp*")), "temporary files left behind"


def test_demo_npz_matches_csv(tmp_path):
    assert main(["demo", "--out", str(tmp_path / "a"), "--no-figures", *SHORT_DEMO]) == 0
    assert main(["demo", "--out", str(tmp_path / "b"), "--no-figures", "--format", "npz", *SHORT_DEMO]) == 0
    data = np.load(tmp_path / "b" / "trace.npz")
    with open(tmp_path / "a" / "trace.csv") as f:
        rows = list(csv.DictReader(f))
    np.testing.assert_allclose(data["i_q"], [float(r["i_q"]) for r in rows], rtol=1e-12, atol=1e-12)


def _status(argv) -> int:
    """main's exit status, also for a flag refused while parsing (argparse exits with SystemExit(2);
    --substeps and --speed-bandwidth are checked there)."""
    try:
        return main(argv)
    except SystemExit as done:
        return done.code


@pytest.mark.parametrize(
    "bad, field",
    [
        # Messages name the flag as typed, not the field ("n_substeps", "duration_s").
        (["--substeps", "0"], "--substeps"),
        (["--duration-s", "0.30005"], "--duration-s"),
        (["--motor", "no_such_motor.toml"], "no_such_motor"),
        (["--speed-bandwidth", "-5"], "bandwidth"),
    ],
)
def test_bad_demo_input_fails_before_writing(tmp_path, capsys, bad, field):
    out = tmp_path / "never"
    assert _status(["demo", "--out", str(out), *SHORT_DEMO, *bad]) == 2
    assert field in capsys.readouterr().err
    assert not out.exists()


def test_replay_command_writes_replay_csv(tmp_path):
    t = np.arange(200) * 1e-4
    log = tmp_path / "log.csv"
    np.savetxt(
        log,
        np.column_stack([t, np.full_like(t, 2.0), np.full_like(t, 20.0), np.full_like(t, 50.0)]),
        delimiter=",",
        header="time,u_d,u_q,omega_m",
        comments="",
    )
    assert main(["replay", str(log), "--motor", "book", "--out", str(tmp_path / "r")]) == 0
    with open(tmp_path / "r" / "replay.csv") as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == ["time", "i_d", "i_q", "omega_m", "theta_e"] and len(rows) == 200
    assert float(rows[-1]["omega_m"]) == pytest.approx(50.0)


def test_replay_missing_column_is_an_error(tmp_path, capsys):
    log = tmp_path / "log.csv"
    log.write_text("time,u_d\n0,1\n0.0001,1\n")
    assert main(["replay", str(log), "--motor", "book", "--out", str(tmp_path / "r")]) == 2
    assert "u_q" in capsys.readouterr().err
    assert not (tmp_path / "r" / "replay.csv").exists()
