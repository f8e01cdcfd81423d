"""The drive file (:mod:`pmsmjax.io.drive_files`): every careless file is refused with one line naming the
table and key, the value and the fix; the values a file leaves out are derived as hand calculations and
scipy solves give them.

Careless files are the shipped presets with one line changed (the presets themselves are accepted, so the
change is what is refused).
"""

import math
import re
from pathlib import Path

import numpy as np
import pytest
from scipy import optimize

from pmsmjax.io.drive_files import PRESET_FOLDER, drive_spec, read_drive_file
from pmsmjax.spec.validation import ParameterError

BOOK = (PRESET_FOLDER / "book.toml").read_text()
SERVO = (PRESET_FOLDER / "servo_400w_48v.toml").read_text()
SIX = (PRESET_FOLDER / "six_phase_book.toml").read_text()
FIVE = (PRESET_FOLDER / "five_phase_book.toml").read_text()
RPM = math.pi / 30.0


def edited(tmp_path, text: str, old: str, new: str, name: str = "drive.toml") -> Path:
    """``text`` with the line starting with ``old`` (the line ``old`` exactly when it ends in a newline)
    replaced by ``new`` (deleted for ``""``), as a file."""
    lines = text.splitlines()
    hits = [
        i
        for i, line in enumerate(lines)
        if (line == old[:-1] if old.endswith("\n") else line.startswith(old))
    ]
    assert len(hits) == 1, f"{old!r} is not one line of the preset"
    lines[hits[0] : hits[0] + 1] = [new] if new else []
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return path


def refusal(path, **kwargs) -> str:
    with pytest.raises(ParameterError) as info:
        drive_spec(path, **kwargs)
    message = str(info.value)
    assert "\n" not in message and "Traceback" not in message
    return message


CARELESS = {
    # (preset text, line start, replacement): fragments the message must hold (table and key, value, fix)
    "inductance in mH": (
        BOOK,
        "L_d = 0.00525",
        "L_d = 5.25",
        ["[motor]", "L_d = 5.25 H", "mH", "write 0.00525"],
    ),
    "resistance in mohm": (BOOK, "R = 0.958", "R = 958.0", ["[motor]", "R = 958 ohm", "write 0.958"]),
    "DC link in kV": (BOOK, "u_dc_v = 311", "u_dc_v = 0.311", ["[inverter] u_dc_v = 0.311 V", "write 311"]),
    "switching in kHz": (
        BOOK,
        "switching_frequency_hz",
        "switching_frequency_hz = 10.0",
        ["[inverter] switching_frequency_hz = 10 Hz", "kHz: write 10000"],
    ),
    "dead time in us": (
        SERVO,
        "dead_time_s",
        "dead_time_s = 0.5",
        ["[inverter] dead_time_s = 0.5 s", "longer than the 50 us switching period", "2e-6"],
    ),
    "dead time over the period": (
        BOOK,
        "dead_time_s",
        "dead_time_s = 1.2e-4",
        ["[inverter] dead_time_s", "longer than the 100 us"],
    ),
    "dead time half the period": (
        BOOK,
        "dead_time_s",
        "dead_time_s = 5e-5",
        ["[inverter] dead_time_s", "50 % of the 100 us"],
    ),
    "device drop in mV": (
        SERVO,
        "dead_time_s",
        "dead_time_s = 5e-7\ndevice_drop_v = 700.0",
        ["[inverter] device_drop_v = 700 V", "above 10 V", "0.7-3 V", "write e.g. 1.5"],
    ),
    "device drop over the DC link's tenth": (
        SERVO,
        "dead_time_s",
        "dead_time_s = 5e-7\ndevice_drop_v = 6.0",
        ["[inverter] device_drop_v = 6 V", "10 % of the 48 V DC link"],
    ),
    "compensation not a bool": (
        SERVO,
        "dead_time_s",
        "dead_time_s = 5e-7\ndead_time_compensation = 1",
        ["[inverter] dead_time_compensation must be true or false, got 1"],
    ),
    "control faster than twice the PWM": (
        BOOK,
        "switching_frequency_hz",
        "switching_frequency_hz = 10000.0\ncontrol_frequency_hz = 50000.0",
        ["[inverter] control_frequency_hz = 50000 Hz", "give 10000 or 20000"],
    ),
    "max current below rated": (
        BOOK,
        "max_current_a",
        "max_current_a = 5.0",
        ["[ratings] max_current_a = 5 A", "below", "9.12 A", "raise max_current_a"],
    ),
    "max current below given rated current": (
        BOOK,
        "max_current_a",
        "max_current_a = 5.0\nrated_current_a = 9.2",
        ["[ratings] max_current_a = 5 A", "below rated_current_a 9.2 A"],
    ),
    "rated torque above the rated current's": (
        BOOK,
        "max_current_a",
        "rated_current_a = 5.0",
        ["[ratings] rated_torque_nm = 10 N m", "rated_current_a = 5 A", "5.48 N m", "give only one"],
    ),
    "rated speed beyond any motor": (
        BOOK,
        "rated_speed_rpm",
        "rated_speed_rpm = 300000.0",
        ["[ratings] rated_speed_rpm = 300000", "200000"],
    ),
    "unknown table": (BOOK, "[ratings]", "[ratngs]", ["unknown tables ['ratngs']", "looks like 'ratings'"]),
    "unknown key": (
        BOOK,
        "L_d = 0.00525",
        "Ld = 0.00525",
        ["unknown keys ['Ld'] in [motor]", "looks like 'L_d'"],
    ),
    "unknown inverter key": (
        BOOK,
        "u_dc_v = 311",
        "udc_v = 311.0",
        ["[inverter]", "'udc_v' looks like 'u_dc_v'", "allowed"],
    ),
    "missing motor field": (BOOK, "J = 0.003", "", ["lacks J in [motor]", "J kg m^2"]),
    "loose key next to [motor]": (BOOK, "# The book", "R = 1.0", ["keys ['R'] sit outside any table"]),
    "number as text": (
        BOOK,
        "R = 0.958",
        'R = "0.958"',
        ["[motor] R must be a finite number (ohm)", "'0.958'"],
    ),
    "pole pairs as float": (BOOK, "pole_pairs", "pole_pairs = 4.0", ["[motor] pole_pairs", "whole number"]),
    "bool for a number": (
        BOOK,
        "u_dc_v = 311",
        "u_dc_v = true",
        ["[inverter] u_dc_v must be a number (V)", "True"],
    ),
    "text for trust_units": (
        BOOK,
        "pole_pairs",
        'pole_pairs = 4\ntrust_units = "yes"',
        ["trust_units", "true or false"],
    ),
    "negative inertia": (BOOK, "J = 0.003", "J = -0.003", ["[motor] J = -0.003 kg m^2", "> 0"]),
    "nan resistance": (BOOK, "R = 0.958", "R = nan", ["[motor] R must be a finite number", "nan"]),
    "inf DC link": (
        BOOK,
        "u_dc_v = 311",
        "u_dc_v = inf",
        ["[inverter] u_dc_v = inf V", "finite number above 0"],
    ),
    "-inf load": (BOOK, "load_nm = 10.0", "load_nm = -inf", ["[scenario] load_nm = -inf N m", "finite"]),
    "nan tuning bound": (BOOK, "load_nm = [", "load_nm = [0.0, nan]", ["[tuning] load_nm", "two finite"]),
    "tuning range reversed": (
        BOOK,
        "speed_rpm = [",
        "speed_rpm = [1500.0, 200.0]",
        ["[tuning] speed_rpm = [1500, 200]", "low <= high"],
    ),
    "tuning range of one number": (
        BOOK,
        "duration_s = [",
        "duration_s = 0.4",
        ["[tuning] duration_s", "[low, high]"],
    ),
    "tolerance of 100 %": (BOOK, "R = 0.2", "R = 1.0", ["[tolerances] R = 1", "below 1", "0.05 for +-5 %"]),
    "tolerance in percent": (BOOK, "psi_f = 0.1\n", "psi_f = 10.0", ["[tolerances] psi_f = 10", "1000 %"]),
    "load after the run": (
        BOOK,
        "load_time_s",
        "load_time_s = 0.5",
        ["[scenario] load_time_s = 0.5 s", "below"],
    ),
    "encoder without lines": (
        BOOK,
        "[tolerances]",
        '[sensor]\nkind = "encoder"\n\n[tolerances]',
        ["[sensor] lines", "e.g. 2500", "None"],
    ),
    "encoder of zero lines": (
        BOOK,
        "[tolerances]",
        '[sensor]\nkind = "encoder"\nlines = 0\n\n[tolerances]',
        ["[sensor] lines", "got 0"],
    ),
    "unknown sensor": (
        BOOK,
        "[tolerances]",
        '[sensor]\nkind = "hall"\n\n[tolerances]',
        ["[sensor] kind = 'hall'"],
    ),
    "lines on an exact sensor": (
        BOOK,
        "[tolerances]",
        "[sensor]\nlines = 2500\n\n[tolerances]",
        ["[sensor] lines", 'kind = "encoder" only'],
    ),
    "load before the run": (
        BOOK,
        "load_time_s",
        "load_time_s = -0.1",
        ["[scenario] load_time_s = -0.1 s", ">= 0"],
    ),
    "six phases as a float": (
        SIX,
        "n_phases",
        "n_phases = 6.0",
        ["[motor] n_phases = 6.0", "give 3, 5 or 6"],
    ),
    "four phases": (
        BOOK,
        "pole_pairs",
        "pole_pairs = 4\nn_phases = 4",
        ["[motor] n_phases = 4", "3, 5 or 6"],
    ),
    "leakage on a three-phase motor": (
        BOOK,
        "pole_pairs",
        "pole_pairs = 4\nL_ls = 0.0005",
        ["[motor] L_ls", "set n_phases or drop them"],
    ),
    "six-phase without leakage": (SIX, "L_ls", "", ["lacks L_ls in [motor]"]),
    "third harmonic on six phases": (SIX, "L_ls", "L_ls = 0.00013125\npsi_f3 = 0.01", ["[motor] psi_f3"]),
    "current bandwidth in Hz x 1000": (
        BOOK,
        "current_bandwidth_rad_s",
        "current_bandwidth_rad_s = 1.1e6",
        ["[control] current_bandwidth_rad_s = 1.1e+06 rad/s", "below 10472", "design rule gives 2909"],
    ),
    "speed loop above the current loop": (
        BOOK,
        "speed_bandwidth_rad_s",
        "speed_bandwidth_rad_s = 5000.0",
        ["[control] speed_bandwidth_rad_s = 5000 rad/s", "not below the current loop's 1100"],
    ),
    "encoder latency in us": (
        BOOK,
        "[tolerances]",
        '[sensor]\nkind = "encoder"\nlines = 2500\ndelay_s = 5.0\n\n[tolerances]',
        ["[sensor] delay_s = 5 s", "more than 10 control periods (1000 us)", "2e-6"],
    ),
}


@pytest.mark.parametrize("name", ["book", "servo-400w"])
def test_the_unedited_presets_are_accepted(name):
    """The careless files below differ from these in one line each: that line is what is refused."""
    assert drive_spec(name).notes == ()


@pytest.mark.parametrize("case", list(CARELESS))
def test_careless_file_is_refused_in_one_line(tmp_path, case):
    text, old, new, fragments = CARELESS[case]
    n_phases = 6 if text is SIX else 3
    path = edited(tmp_path, text, old, new)
    message = refusal(path, n_phases=n_phases)
    assert str(path) in message
    for fragment in fragments:
        assert fragment in message, f"{fragment!r} not in {message!r}"


def test_multiphase_file_on_a_three_phase_command(tmp_path):
    six = tmp_path / "six.toml"
    six.write_text(SIX)
    message = refusal(six)
    assert "a six-phase motor (n_phases = 6)" in message and "give --machine six-phase" in message
    message = refusal(six, n_phases=5)
    assert "this command runs a five-phase machine" in message
    assert refusal("six_phase_book", n_phases=6).startswith("--motor six_phase_book: neither a preset (book,")


def test_override_flags_are_named_in_the_message():
    message = refusal("book", u_dc_v=0.311, flags={"u_dc_v": "--u-dc"})
    assert message.startswith("--u-dc = 0.311 V") and "write 311" in message
    message = refusal("book", max_current_a=4.0, flags={"max_current_a": "--current-limit"})
    assert message.startswith("--current-limit = 4 A is below")


def test_missing_and_invalid_files(tmp_path):
    assert "neither a preset" in refusal(tmp_path / "absent.toml")
    assert "is a folder" in refusal(tmp_path)
    bad = tmp_path / "bad.toml"
    bad.write_text("[motor]\nR = 0.958\nR = 1.0\n")
    assert "not valid TOML" in refusal(bad)
    bad.write_bytes(b"\xff\xfe[motor]")
    assert "not a text file" in refusal(bad)
    with pytest.raises(ParameterError, match="does not exist: check the path"):
        read_drive_file(tmp_path / "absent.toml")


def _voltage(motor, w_e, i_d, i_q) -> float:
    """Steady-state peak phase voltage (V) in the rotor frame, the book, ch. 1."""
    u_d = motor["R"] * i_d - w_e * motor["L_q"] * i_q
    u_q = motor["R"] * i_q + w_e * (motor["L_d"] * i_d + motor["psi_f"])
    return math.hypot(u_d, u_q)


def test_48v_servo_at_10000_rpm_is_unreachable(tmp_path):
    """The 48 V servo rated at 10000 r/min: the message's needed voltage is the hand-computed steady state,
    and no current within max_current_a (field weakening included) brings it under the inverter's limit."""
    path = edited(tmp_path, SERVO, "rated_speed_rpm", "rated_speed_rpm = 10000.0")
    message = refusal(path)
    motor = drive_spec("servo-400w").motor
    w_m = 10000.0 * RPM
    w_e = motor["pole_pairs"] * w_m
    i_q = (1.27 + motor["B"] * w_m) / (1.5 * motor["pole_pairs"] * motor["psi_f"])
    need = _voltage(motor, w_e, 0.0, i_q)
    limit = 48.0 / math.sqrt(3.0)
    assert f"needs {need:.0f} V peak" in message and f"gives {limit:.0f} V" in message
    assert f"raise u_dc_v to at least {math.ceil(need * math.sqrt(3.0))} V" in message

    # The best field weakening: the least voltage over every current of at most 36 A giving the torque.
    def torque_gap(i):
        i_d, i_q = i
        return 1.5 * motor["pole_pairs"] * i_q * motor["psi_f"] - (1.27 + motor["B"] * w_m)

    best = optimize.minimize(
        lambda i: _voltage(motor, w_e, *i),
        x0=[-20.0, 15.0],
        constraints=[{"type": "eq", "fun": torque_gap}, {"type": "ineq", "fun": lambda i: 36.0**2 - i @ i}],
        method="SLSQP",
    )
    assert best.success and best.fun > 1.2 * limit
    # The speed it offers: where the rated torque (i_d = 0) needs the whole limit.
    top = optimize.brentq(
        lambda rpm: _voltage(motor, motor["pole_pairs"] * rpm * RPM, 0.0,
                             (1.27 + motor["B"] * rpm * RPM) / (6 * motor["psi_f"])) - limit,
        100.0, 10000.0,
    )  # fmt: skip
    assert re.search(r"lower rated_speed_rpm to about (\d+) r/min", message).group(1) == f"{top:.0f}"


def test_rated_point_beyond_the_dc_link(tmp_path):
    message = refusal(edited(tmp_path, BOOK, "u_dc_v = 311", "u_dc_v = 100.0"))
    assert message.count("[ratings] rated_speed_rpm = 1000 r/min") == 1 and "raise u_dc_v" in message


def test_rated_point_in_field_weakening_is_kept_with_a_note(tmp_path):
    """The book motor at 1000 r/min and 10 N m needs 89 V (hand: below); 140 V of DC link gives 80.8 V,
    and field weakening within 15 A closes the gap: the note names the least i_d that does (brentq)."""
    spec = drive_spec(edited(tmp_path, BOOK, "u_dc_v = 311", "u_dc_v = 140.0"))
    motor = spec.motor
    w_m = 1000.0 * RPM
    i_q = (10.0 + motor["B"] * w_m) / (6 * motor["psi_f"])
    need = _voltage(motor, 4 * w_m, 0.0, i_q)
    limit = 140.0 / math.sqrt(3.0)
    assert need > limit
    i_d = optimize.brentq(
        lambda i_d: _voltage(motor, 4 * w_m, i_d, i_q) - limit, -math.sqrt(15**2 - i_q**2), 0.0
    )
    assert len(spec.notes) == 1 and f"needs {need:.0f} V with MTPA" in spec.notes[0]
    assert f"(i_d = {i_d:.3g} A at least); run demo with --field-weakening" in spec.notes[0]


def _mtpa_current(motor, torque) -> float:
    """The least current magnitude giving ``torque``: the most torque of a magnitude over its angle
    (scipy), then the magnitude that gives ``torque`` (root)."""

    def most_torque(current):
        res = optimize.minimize_scalar(
            lambda beta: -1.5 * motor["pole_pairs"] * current * math.cos(beta)
            * (motor["psi_f"] + (motor["L_d"] - motor["L_q"]) * -current * math.sin(beta)),
            bounds=(0.0, math.pi / 2), method="bounded", options={"xatol": 1e-12},
        )  # fmt: skip
        return -res.fun

    return optimize.brentq(lambda i: most_torque(i) - torque, 1e-6, 1e3, xtol=1e-12)


@pytest.mark.parametrize("name", ["book", "book_salient", "industrial-5k6w", "servo-400w"])
def test_rated_current_is_the_mtpa_current_of_the_rated_torque(name):
    spec = drive_spec(name)
    assert spec.derived["ratings.rated_current_a"] == "the MTPA current of the rated torque"
    expected = _mtpa_current(spec.motor, spec.ratings["rated_torque_nm"])
    np.testing.assert_allclose(spec.ratings["rated_current_a"], expected, rtol=1e-7)


def test_book_file_states_the_book(tmp_path):
    """The book drive (docs/book_reference.md, "Reference motor"), read by name and by path alike."""
    spec = drive_spec("book")
    assert spec.motor == dict(R=0.958, L_d=0.00525, L_q=0.00525, psi_f=0.1827, pole_pairs=4, J=0.003, B=0.008)
    assert spec.Ts == 1e-4 and spec.u_dc_v == 311.0 and spec.current_limit_a == 15.0
    assert spec.control["current_bandwidth_rad_s"] == 1100.0 and spec.control["speed_bandwidth_rad_s"] == 50.0
    assert spec.scenario == dict(speed_rpm=1000.0, load_nm=10.0, load_time_s=0.2, duration_s=0.4)
    assert spec.tuning == dict(speed_rpm=[200.0, 1500.0], load_nm=[0.0, 10.0], duration_s=[0.3, 0.5])
    np.testing.assert_allclose(spec.voltage_limit_v, 311.0 / math.sqrt(3.0), rtol=1e-15)
    np.testing.assert_allclose(spec.ratings["rated_current_a"], 10.0 / (6 * 0.1827), rtol=1e-9)
    assert set(spec.derived) == {
        "inverter.control_frequency_hz",
        "inverter.device_drop_v",
        "inverter.dead_time_compensation",
        "ratings.rated_current_a",
    }
    path = tmp_path / "book.toml"
    path.write_text(BOOK)
    by_path = drive_spec(path)
    assert by_path.summary() | {"source": "book"} == spec.summary()


def test_derived_rules_of_a_motor_only_file(tmp_path):
    """Seven values only: the book's 10 kHz and 311 V, the current loop 0.29 / Ts (65 deg phase margin
    against 1.5 periods of delay), rated current 0.26 psi_f / L_d, peak current twice that."""
    path = tmp_path / "motor.toml"
    path.write_text("R = 0.5\nL_d = 0.004\nL_q = 0.004\npsi_f = 0.1\npole_pairs = 3\nJ = 0.002\nB = 0.001\n")
    spec = drive_spec(path)
    assert spec.inverter == dict(u_dc_v=311.0, switching_frequency_hz=1e4, control_frequency_hz=1e4,
                                 dead_time_s=0.0, device_drop_v=0.0, dead_time_compensation=True)  # fmt: skip
    a_c = math.radians(90.0 - 65.0) / (1.5 * 1e-4)
    np.testing.assert_allclose(spec.control["current_bandwidth_rad_s"], a_c, rtol=1e-12)
    assert round(a_c * 1e-4, 2) == 0.29
    np.testing.assert_allclose(spec.ratings["rated_current_a"], 0.26 * 0.1 / 0.004, rtol=1e-12)
    np.testing.assert_allclose(spec.ratings["max_current_a"], 2 * 0.26 * 0.1 / 0.004, rtol=1e-12)
    np.testing.assert_allclose(spec.ratings["rated_torque_nm"], 4.5 * 0.1 * 6.5, rtol=1e-12)
    # Rated speed: the base speed, where the rated point takes 95 % of 311 / sqrt 3 (brentq on the hand
    # formula; the file keeps it to 0.1 r/min).
    i_q = spec.ratings["rated_current_a"]
    base = optimize.brentq(
        lambda rpm: _voltage(spec.motor, 3 * rpm * RPM, 0.0,
                             i_q + 0.001 * rpm * RPM / (4.5 * 0.1)) - 0.95 * 311.0 / math.sqrt(3.0),
        1.0, 1e5, xtol=1e-9,
    )  # fmt: skip
    assert abs(spec.ratings["rated_speed_rpm"] - base) <= 0.05 + 1e-9
    assert spec.scenario["speed_rpm"] == spec.ratings["rated_speed_rpm"]
    np.testing.assert_allclose(spec.scenario["load_nm"], 0.8 * spec.ratings["rated_torque_nm"], rtol=1e-12)
    assert spec.scenario["duration_s"] == 2 * spec.scenario["load_time_s"]
    assert all(key in spec.derived for key in ("inverter.u_dc_v", "ratings.rated_speed_rpm"))


def test_dc_link_derived_from_the_rated_point(tmp_path):
    """No [inverter] u_dc_v: the rated point's voltage with 10 % margin, as a DC link (x sqrt 3)."""
    path = edited(tmp_path, SERVO, "u_dc_v = 48", "")
    spec = drive_spec(path)
    motor = spec.motor
    w_m = 3000.0 * RPM
    need = _voltage(motor, 4 * w_m, 0.0, (1.27 + motor["B"] * w_m) / (6 * motor["psi_f"]))
    assert spec.u_dc_v == math.ceil(1.1 * need * math.sqrt(3.0))


def test_current_loop_rule_at_the_control_rate(tmp_path):
    """20 kHz PWM with control twice per period: Ts = 25 us, a_c = 0.29 / Ts."""
    spec = drive_spec(
        edited(tmp_path, SERVO, "dead_time_s", "dead_time_s = 5e-7\ncontrol_frequency_hz = 40000.0")
    )
    assert spec.Ts == 2.5e-5
    np.testing.assert_allclose(spec.control["current_bandwidth_rad_s"], math.radians(25.0) / (1.5 * 2.5e-5))


def test_encoder_and_tolerances_read(tmp_path):
    text = BOOK.replace(
        "[tolerances]", '[sensor]\nkind = "encoder"\nlines = 2500\ndelay_s = 5e-5\n\n[tolerances]'
    )
    text = text.replace("u_dc_v = 0.1\n", "u_dc_v = 0.0\n")
    path = tmp_path / "enc.toml"
    path.write_text(text)
    spec = drive_spec(path)
    assert spec.sensor == {"kind": "encoder", "lines": 2500, "delay_s": 5e-5}
    assert spec.tolerances["u_dc_v"] == 0.0 and spec.tolerances["J"] == 0.5
