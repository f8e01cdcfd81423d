"""``pmsmjax export --target ti``: the header compiled by the system C compiler in a program that prints its
defines, the printed values converted back with TI's formulas (written here from the SDK's source, not
from the exporter) to the drive's SI gains; the header's series-PI gains run through ``PI_run_series``'s
update (pi.h) against the simulator's forward-Euler PI; the one-line refusals.

TI's formulas, from the MotorControl SDK's universal motor control lab (cited in ``pmsmjax/export/ti.py``):
``motor_ratedFlux_Wb = USER_MOTOR1_RATED_FLUX_VpHz / (2 pi)`` (user_mtr1.c); ``PI_run_series``: ``Up = Kp
e``, ``Ui += Ki Up``, ``u = Up + Ui`` (pi.h); the speed PI in electrical Hz, ``rpm2Hz_sf = p / 60``
(motor1_drive.c).
"""

import json
import math
import subprocess

import numpy as np
import pytest
from test_c_controller import CC, needs_cc

from pmsmjax.cli import main

BOOK = {"R": 0.958, "L": 0.00525, "psi_f": 0.1827, "p": 4, "I_max": 15.0, "Ts": 1e-4}
REL = dict(rel=1e-6)

#: Prints every define of the header by name, then runs TI's series PI (pi.h's PI_run_series without
#: saturation: the linear range) with the header's q-current and speed gains on the errors read from stdin.
PROGRAM = r"""
#include <stdio.h>
#include "ti_user_mtr1.h"

#define SHOW(name) printf(#name " %.9g\n", (double)(name))

static float pi_run_series(float Kp, float Ki, float *Ui, float error)
{
    float Up = Kp * error;
    *Ui = *Ui + (Ki * Up);
    return Up + *Ui;
}

int main(void)
{
    SHOW(USER_MOTOR1_NUM_POLE_PAIRS);
    SHOW(USER_MOTOR1_Rs_Ohm);
    SHOW(USER_MOTOR1_Ls_d_H);
    SHOW(USER_MOTOR1_Ls_q_H);
    SHOW(USER_MOTOR1_RATED_FLUX_VpHz);
    SHOW(USER_MOTOR1_MAX_CURRENT_A);
    SHOW(USER_M1_PWM_FREQ_kHz);
    SHOW(USER_M1_NUM_PWM_TICKS_PER_ISR_TICK);
    SHOW(USER_M1_NUM_ISR_TICKS_PER_SPEED_TICK);
    SHOW(PMSMJAX_M1_KP_ID_VpA);
    SHOW(PMSMJAX_M1_KI_ID);
    SHOW(PMSMJAX_M1_KP_IQ_VpA);
    SHOW(PMSMJAX_M1_KI_IQ);
    SHOW(PMSMJAX_M1_KP_SPD_ApHz);
    SHOW(PMSMJAX_M1_KI_SPD);
    float ui_q = 0.0f, ui_spd = 0.0f, error;
    while (scanf("%f", &error) == 1)
        printf("u %.9g %.9g\n", (double)pi_run_series(PMSMJAX_M1_KP_IQ_VpA, PMSMJAX_M1_KI_IQ, &ui_q, error),
               (double)pi_run_series(PMSMJAX_M1_KP_SPD_ApHz, PMSMJAX_M1_KI_SPD, &ui_spd, error));
    return 0;
}
"""


def export_ti(tmp_path, *flags):
    """Run ``pmsmjax export --target ti``; returns the folder and the JSON's ``{name: value}``."""
    out = tmp_path / "ti"
    assert main(["export", "--target", "ti", "--out", str(out), *map(str, flags)]) == 0
    body = json.loads((out / "ti_user_mtr1.json").read_text())
    assert body["target"] == "ti"
    return out, {name: entry["value"] for name, entry in body["parameters"].items()}


def book_description():
    from pmsmjax.export.build import export_drive
    from pmsmjax.export.description import describe
    from pmsmjax.io.drive_files import drive_spec

    return describe(export_drive(drive_spec("book")), "book")


def si_from_series(Kp: float, Ki: float, Ts: float) -> tuple[float, float]:
    """The forward-Euler PI whose difference equation TI's series PI runs: ``u_k = Kp (1 + Ki) e_k + Kp Ki
    sum_{j<k} e_j`` = ``kp e_k + ki Ts sum_{j<k} e_j``."""
    return Kp * (1.0 + Ki), Kp * Ki / Ts


def compile_and_run(folder, errors) -> tuple[dict, np.ndarray]:
    source = folder / "show.c"
    source.write_text(PROGRAM)
    exe = folder / "show"
    built = subprocess.run(
        [CC, "-std=c99", "-Wall", "-Wextra", "-Werror", "-I", str(folder), "-o", str(exe), str(source)],
        capture_output=True,
        text=True,
    )
    assert built.returncode == 0, f"the TI header does not compile:\n{built.stderr}"
    ran = subprocess.run(
        [str(exe)], input="\n".join(f"{e:.9g}" for e in errors), capture_output=True, text=True, check=True
    )
    values, outputs = {}, []
    for line in ran.stdout.splitlines():
        name, *numbers = line.split()
        if name == "u":
            outputs.append([float(x) for x in numbers])
        else:
            values[name] = float(numbers[0])
    return values, np.array(outputs)


@needs_cc
def test_ti_header_compiles_and_converts_back(tmp_path):
    d = book_description()
    out, _ = export_ti(tmp_path, "--motor", "book")
    errors = np.random.default_rng(3).normal(size=1500)
    v, u = compile_and_run(out, errors)

    p = BOOK["p"]
    assert v["USER_MOTOR1_NUM_POLE_PAIRS"] == p
    assert v["USER_MOTOR1_Rs_Ohm"] == pytest.approx(BOOK["R"], **REL)
    assert v["USER_MOTOR1_Ls_d_H"] == pytest.approx(BOOK["L"], **REL)
    assert v["USER_MOTOR1_Ls_q_H"] == pytest.approx(BOOK["L"], **REL)
    # user_mtr1.c: motor_ratedFlux_Wb = USER_MOTOR1_RATED_FLUX_VpHz / MATH_TWO_PI
    assert v["USER_MOTOR1_RATED_FLUX_VpHz"] / (2 * math.pi) == pytest.approx(BOOK["psi_f"], **REL)
    assert v["USER_MOTOR1_MAX_CURRENT_A"] == BOOK["I_max"]
    # ctrlFreq_Hz = USER_M1_PWM_FREQ_kHz * 1000 / USER_M1_NUM_PWM_TICKS_PER_ISR_TICK
    Ts = v["USER_M1_NUM_PWM_TICKS_PER_ISR_TICK"] / (v["USER_M1_PWM_FREQ_kHz"] * 1000.0)
    assert Ts == pytest.approx(BOOK["Ts"], **REL)
    Ts_speed = v["USER_M1_NUM_ISR_TICKS_PER_SPEED_TICK"] * Ts
    assert Ts_speed == pytest.approx(d.speed_period_s, **REL)

    for axis, kp, ki in (("ID", d.current_kp_d, d.current_ki_d), ("IQ", d.current_kp_q, d.current_ki_q)):
        back = si_from_series(v[f"PMSMJAX_M1_KP_{axis}_VpA"], v[f"PMSMJAX_M1_KI_{axis}"], Ts)
        assert back == pytest.approx((kp, ki), **REL)
        # the book's current loop: kp = 1100 rad/s * L, ki = 1100 rad/s * R
        assert back == pytest.approx((1100 * BOOK["L"], 1100 * BOOK["R"]), **REL)
    # the speed PI's error is in electrical Hz: rad/s (mechanical) = Hz_e * 2 pi / p
    kp_hz, ki_hz = si_from_series(v["PMSMJAX_M1_KP_SPD_ApHz"], v["PMSMJAX_M1_KI_SPD"], Ts_speed)
    assert kp_hz * p / (2 * math.pi) == pytest.approx(d.speed_kp + d.speed_active_damping, **REL)
    assert ki_hz * p / (2 * math.pi) == pytest.approx(d.speed_ki, **REL)

    # the header's gains in pi.h's series update are the simulator's forward-Euler PI (float32 in C)
    for column, (kp, ki, period) in enumerate(
        ((d.current_kp_q, d.current_ki_q, Ts), (kp_hz, ki_hz, Ts_speed))
    ):
        x, euler = 0.0, []
        for e in errors:
            euler.append(kp * e + x)
            x += ki * period * e
        euler = np.array(euler)
        assert np.max(np.abs(u[:, column] - euler)) <= 1e-5 * np.max(np.abs(euler))


def test_ti_salient_drive_keeps_its_d_and_q_gains(tmp_path):
    """TI's lab runs separate Id and Iq PIs (``Kp_Id = Ls_d BWc``, ``Kp_Iq = Ls_q BWc``): a salient drive's
    unequal d and q gains are written, not refused."""
    from pmsmjax.export.build import export_drive
    from pmsmjax.export.description import describe
    from pmsmjax.io.drive_files import drive_spec

    d = describe(export_drive(drive_spec("industrial-5k6w")), "industrial-5k6w")
    _, v = export_ti(tmp_path, "--motor", "industrial-5k6w")
    assert v["USER_MOTOR1_Ls_d_H"] == pytest.approx(d.L_d_h, **REL) != v["USER_MOTOR1_Ls_q_H"]
    for axis, kp, ki in (("ID", d.current_kp_d, d.current_ki_d), ("IQ", d.current_kp_q, d.current_ki_q)):
        back = si_from_series(v[f"PMSMJAX_M1_KP_{axis}_VpA"], v[f"PMSMJAX_M1_KI_{axis}"], d.Ts_s)
        assert back == pytest.approx((kp, ki), **REL)
    assert v["USER_M1_NUM_ISR_TICKS_PER_SPEED_TICK"] == d.speed_divider


def refused(argv, capsys) -> str:
    assert main(["export", *map(str, argv)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("pmsmjax export: error: "), err
    return err


def test_ti_refuses_field_weakening(tmp_path, capsys):
    out = tmp_path / "out"
    err = refused(["--target", "ti", "--field-weakening", "--out", out], capsys)
    assert "--target ti" in err and "--field-weakening" in err and "--target c" in err
    assert not out.exists()


def test_ti_refuses_a_gain_pair_without_a_positive_series_kp(tmp_path, capsys):
    gains = tmp_path / "gains.toml"
    # ki Ts = 1000 * 1e-4 = 0.1 > kp: TI's series Kp = kp - ki Ts would be negative
    gains.write_text('[gains]\n"controller.current.kp_q" = 0.05\n"controller.current.ki_q" = 1000.0\n')
    out = tmp_path / "out"
    err = refused(["--target", "ti", "--gains", gains, "--out", out], capsys)
    assert "PMSMJAX_M1_KP_IQ_VpA" in err and "--gains" in err, err
    assert not out.exists()
