"""``pmsmjax export --target odrive | simplefoc``: the drive's gains in the vendor's names and units,
checked against a hand computation from the vendor's documented formulas (the book drive, design rules and
a tuned gains file), the vendor's inverse (round trip), the discretisation claim (SimpleFOC's Tustin PI with
``P = kp - ki Ts/2`` is the simulator's forward-Euler PI), and the one-line refusals."""

import json
import math

import numpy as np
import pytest

from pmsmjax.cli import main

BOOK = {"R": 0.958, "L": 0.00525, "psi_f": 0.1827, "p": 4, "I_max": 15.0, "u_dc": 311.0, "Ts": 1e-4}


def export(tmp_path, target, *flags) -> dict:
    """Run ``pmsmjax export --target TARGET``; returns the JSON's parameters ``{name: value}``."""
    out = tmp_path / target
    assert main(["export", "--target", target, "--out", str(out), *map(str, flags)]) == 0
    body = json.loads(
        (out / f"{'odrive_config' if target == 'odrive' else 'simplefoc_gains'}.json").read_text()
    )
    assert body["target"] == target
    return {name: entry["value"] for name, entry in body["parameters"].items()}


def book_gains():
    """The book drive's design-rule gains as the simulator holds them (float32)."""
    from pmsmjax.export.build import export_drive
    from pmsmjax.export.description import describe
    from pmsmjax.io.drive_files import drive_spec

    return describe(export_drive(drive_spec("book")), "book")


def gains_file(tmp_path, gains: dict):
    path = tmp_path / "gains.toml"
    path.write_text("[gains]\n" + "".join(f'"{k}" = {v!r}\n' for k, v in gains.items()))
    return path


def test_odrive_book_by_hand(tmp_path):
    d = book_gains()
    v = export(tmp_path, "odrive", "--motor", "book")
    kt = 1.5 * BOOK["p"] * BOOK["psi_f"]  # N m per peak A of Iq
    rel = dict(rel=1e-6)
    assert v["axis0.motor.config.torque_constant"] == pytest.approx(kt, **rel)
    # the book's current loop is kp = 1100 rad/s * L, ki = 1100 rad/s * R: ODrive's own formula
    assert v["axis0.motor.config.current_control_bandwidth"] == pytest.approx(1100.0, **rel)
    assert v["axis0.motor.config.phase_resistance"] == pytest.approx(BOOK["R"], **rel)
    assert v["axis0.motor.config.phase_inductance"] == pytest.approx(BOOK["L"], **rel)
    assert v["axis0.motor.config.current_lim"] == BOOK["I_max"]
    assert v["axis0.motor.config.pole_pairs"] == BOOK["p"]
    # Nm/(turn/s): A/(rad/s) * (N m/A) * (rad/turn)
    assert v["axis0.controller.config.vel_gain"] == pytest.approx(
        (d.speed_kp + d.speed_active_damping) * kt * 2 * math.pi, **rel
    )
    assert v["axis0.controller.config.vel_integrator_gain"] == pytest.approx(
        d.speed_ki * kt * 2 * math.pi, **rel
    )
    assert v["axis0.controller.config.vel_limit"] == pytest.approx(1000.0 / 60.0)
    text = (tmp_path / "odrive" / "odrive_config.txt").read_text()
    assert "odrv0.axis0.controller.config.vel_gain = " in text
    assert "odrv0.axis0.controller.config.control_mode = CONTROL_MODE_VELOCITY_CONTROL" in text


def test_odrive_tuned_gains_round_trip(tmp_path):
    from pmsmjax.export.odrive import si_gains_from_odrive

    kp_i = 4.2
    ki_i = kp_i * BOOK["R"] / BOOK["L"]  # ODrive's i_gain = bw R: a pair it can hold
    gains = {
        "controller.speed.kp": 0.21,
        "controller.speed.ki": 7.5,
        "controller.speed.active_damping": 0.05,
        **{f"controller.current.kp_{a}": kp_i for a in "dq"},
        **{f"controller.current.ki_{a}": ki_i for a in "dq"},
    }
    v = export(tmp_path, "odrive", "--motor", "book", "--gains", gains_file(tmp_path, gains))
    back = si_gains_from_odrive(v)
    assert back["speed_kp"] == pytest.approx(0.21 + 0.05, rel=1e-6)
    assert back["speed_ki"] == pytest.approx(7.5, rel=1e-6)
    assert back["current_kp"] == pytest.approx(kp_i, rel=1e-6)
    assert back["current_ki"] == pytest.approx(ki_i, rel=1e-5)
    assert v["axis0.motor.config.current_control_bandwidth"] == pytest.approx(kp_i / BOOK["L"], rel=1e-6)


def test_simplefoc_book_by_hand_and_round_trip(tmp_path):
    from pmsmjax.export.simplefoc import kp_from_tustin

    d = book_gains()
    v = export(tmp_path, "simplefoc", "--motor", "book")
    Ts, rel = BOOK["Ts"], dict(rel=1e-6)
    for axis in "qd":
        assert v[f"PID_current_{axis}.P"] == pytest.approx(
            1100 * BOOK["L"] - 1100 * BOOK["R"] * Ts / 2, **rel
        )
        assert v[f"PID_current_{axis}.I"] == pytest.approx(1100 * BOOK["R"], **rel)
        assert v[f"PID_current_{axis}.limit"] == pytest.approx(BOOK["u_dc"] / math.sqrt(3), **rel)
    kp = d.speed_kp + d.speed_active_damping
    assert v["PID_velocity.P"] == pytest.approx(kp - d.speed_ki * Ts / 2, **rel)
    assert v["PID_velocity.I"] == pytest.approx(d.speed_ki, **rel)
    assert v["PID_velocity.limit"] == v["current_limit"] == BOOK["I_max"]
    assert v["LPF_velocity.Tf"] == 0.0 and v["PID_velocity.output_ramp"] == 0.0
    assert kp_from_tustin(v["PID_velocity.P"], v["PID_velocity.I"], Ts) == pytest.approx(kp, **rel)
    assert kp_from_tustin(v["PID_current_q.P"], v["PID_current_q.I"], Ts) == pytest.approx(
        d.current_kp_q, **rel
    )
    text = (tmp_path / "simplefoc" / "simplefoc_gains.h").read_text()
    assert "motor.torque_controller = TorqueControlType::foc_current;" in text


def test_simplefoc_tuned_gains(tmp_path):
    gains = {"controller.speed.kp": 0.21, "controller.speed.ki": 7.5, "controller.current.kp_d": 4.2}
    v = export(tmp_path, "simplefoc", "--motor", "book", "--gains", gains_file(tmp_path, gains))
    d = book_gains()
    assert v["PID_current_d.P"] == pytest.approx(4.2 - d.current_ki_d * BOOK["Ts"] / 2, rel=1e-6)
    assert v["PID_current_q.P"] == pytest.approx(d.current_kp_q - d.current_ki_q * BOOK["Ts"] / 2, rel=1e-6)
    assert v["PID_velocity.P"] == pytest.approx(
        0.21 + d.speed_active_damping - 7.5 * BOOK["Ts"] / 2, rel=1e-6
    )


def test_simplefoc_tustin_pid_is_the_simulators_forward_euler_pi():
    """SimpleFOC's pid.cpp (Tustin integral, integral and output clamps) with ``P = kp - ki Ts/2`` gives
    the forward-Euler PI's output ``kp e_k + ki Ts sum_{j<k} e_j`` in the linear range."""
    kp, ki, Ts, limit = 5.775, 1053.8, 1e-4, 1e9
    p_gain, i_gain = kp - ki * Ts / 2, ki
    e = np.random.default_rng(1).normal(size=2000)
    integral_prev = error_prev = 0.0
    x = 0.0
    for k in range(len(e)):
        integral = min(max(integral_prev + i_gain * Ts * 0.5 * (e[k] + error_prev), -limit), limit)
        simplefoc = min(max(p_gain * e[k] + integral, -limit), limit)
        euler = kp * e[k] + x
        assert simplefoc == pytest.approx(euler, rel=1e-9, abs=1e-9)
        integral_prev, error_prev, x = integral, e[k], x + Ts * ki * e[k]


def refused(argv, capsys) -> str:
    assert main(["export", *map(str, argv)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("pmsmjax export: error: "), err
    return err


@pytest.mark.parametrize(
    "flags, names",
    [
        (["--target", "odrive", "--motor", "industrial-5k6w"], ["--target odrive", "kp_d", "--target c"]),
        (["--target", "odrive", "--field-weakening"], ["--target odrive", "--field-weakening"]),
        (["--target", "simplefoc", "--field-weakening"], ["--target simplefoc", "--field-weakening"]),
    ],
    ids=["odrive-salient-gains", "odrive-fw", "simplefoc-fw"],
)
def test_vendor_refusals_write_nothing(tmp_path, capsys, flags, names):
    out = tmp_path / "out"
    err = refused([*flags, "--out", out], capsys)
    for name in names:
        assert name in err, err
    assert not out.exists()


def test_odrive_refuses_a_current_pair_it_cannot_hold(tmp_path, capsys):
    gains = gains_file(tmp_path, {"controller.current.kp_d": 4.2, "controller.current.kp_q": 4.2})
    out = tmp_path / "out"
    err = refused(["--target", "odrive", "--gains", gains, "--out", out], capsys)
    assert "ki/kp" in err and "R/L" in err and "--target c" in err
    assert not out.exists()


def test_simplefoc_refuses_a_gain_pair_without_a_positive_p(tmp_path, capsys):
    gains = gains_file(tmp_path, {"controller.current.kp_q": 0.01, "controller.current.ki_q": 1000.0})
    out = tmp_path / "out"
    err = refused(["--target", "simplefoc", "--gains", gains, "--out", out], capsys)
    assert "PID_current_q.P" in err and "--gains" in err
    assert not out.exists()
