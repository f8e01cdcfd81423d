"""``pmsmjax export --target vesc``: the book drive's gains in VESC's mcconf names and units, checked against
a hand computation from the firmware's speed PID (``foc_math.c``: ERPM error, ``/20``, output times
``lo_current_max``) and VESC Tool's detection rules, the PID's inverse, and the one-line refusals."""

import json
import math

import pytest

from pmsmjax.cli import main

BOOK = {"R": 0.958, "L": 0.00525, "psi_f": 0.1827, "p": 4, "I_max": 15.0}


def export_vesc(tmp_path, *flags) -> dict:
    out = tmp_path / "vesc"
    assert main(["export", "--target", "vesc", "--out", str(out), *map(str, flags)]) == 0
    body = json.loads((out / "vesc_mcconf.json").read_text())
    assert body["target"] == "vesc"
    assert "foc_current_kp = " in (out / "vesc_mcconf.txt").read_text()
    return {name: entry["value"] for name, entry in body["parameters"].items()}


def test_vesc_book_by_hand(tmp_path):
    from pmsmjax.export.build import export_drive
    from pmsmjax.export.description import describe
    from pmsmjax.io.drive_files import drive_spec

    d = describe(export_drive(drive_spec("book")), "book")
    v = export_vesc(tmp_path, "--motor", "book")
    rel = dict(rel=1e-6)
    assert v["foc_motor_r"] == pytest.approx(BOOK["R"], **rel)
    assert v["foc_motor_l"] == pytest.approx(BOOK["L"], **rel) and v["foc_motor_ld_lq_diff"] == 0.0
    assert v["foc_motor_flux_linkage"] == pytest.approx(BOOK["psi_f"], **rel)
    # VESC Tool's detection: kp = L bw, ki = R bw (the book's 1100 rad/s), observer gain 1e-3/lambda^2 * 1e6
    assert v["foc_current_kp"] == pytest.approx(1100 * BOOK["L"], **rel)
    assert v["foc_current_ki"] == pytest.approx(1100 * BOOK["R"], **rel)
    assert v["foc_observer_gain"] == pytest.approx(1e3 / BOOK["psi_f"] ** 2, **rel)
    # the firmware's speed PID on an error of 1 rad/s (mechanical): iq* = I_max * (e_erpm * s_pid_kp / 20)
    e_erpm = 1.0 * BOOK["p"] * 60 / (2 * math.pi)
    iq = BOOK["I_max"] * e_erpm * v["s_pid_kp"] / 20
    assert iq == pytest.approx(d.speed_kp + d.speed_active_damping, **rel)
    assert BOOK["I_max"] * e_erpm * v["s_pid_ki"] / 20 == pytest.approx(d.speed_ki, **rel)
    assert v["l_current_max"] == BOOK["I_max"]


def test_vesc_refuses_unequal_current_gains(tmp_path, capsys):
    gains = tmp_path / "gains.toml"
    gains.write_text('[gains]\n"controller.current.kp_d" = 4.2\n')
    out = tmp_path / "out"
    assert main(["export", "--target", "vesc", "--gains", str(gains), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--target vesc" in err and "foc_current_kp" in err, err
    assert not out.exists()
