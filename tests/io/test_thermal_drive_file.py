"""A warm motor's drive file: ``[motor]`` temperature coefficients, ``[thermal]`` and ``[operating]``.

The book preset with the tables added is accepted and completed (defaults noted in ``derived``), builds a
drive whose thermal part holds the file's values in kelvin, and careless values are refused in one line that
names the key and the fix, in the user's units (a coefficient in %/K, a temperature in K).
"""

import numpy as np
import pytest

from pmsmjax.io.drive_files import PRESET_FOLDER, drive_spec
from pmsmjax.spec.validation import ParameterError

BOOK = (PRESET_FOLDER / "book.toml").read_text()
THERMAL = """
[thermal]
r_th_k_per_w = 0.5
c_th_j_per_k = 1500.0
initial_c = 90.0

[operating]
winding_temperature_c = [20.0, 120.0]
u_dc_v = [280.0, 330.0]
ambient_c = [0.0, 40.0]
"""


def warm_file(tmp_path, motor_extra: str = "", thermal: str = THERMAL):
    text = BOOK.replace("B = 0.008            # N m s/rad", "B = 0.008\n" + motor_extra) + thermal
    path = tmp_path / "warm.toml"
    path.write_text(text)
    return path


def refusal(path) -> str:
    with pytest.raises(ParameterError) as info:
        drive_spec(path)
    message = str(info.value)
    assert "\n" not in message
    return message


def test_accepted_and_completed(tmp_path):
    spec = drive_spec(warm_file(tmp_path))
    assert dict(spec.thermal) == {
        "r_th_k_per_w": 0.5, "c_th_j_per_k": 1500.0, "ambient_c": 40.0, "initial_c": 90.0
    }  # fmt: skip
    assert spec.motor["r_temp_coeff_per_k"] == 0.00393
    assert spec.motor["psi_f_temp_coeff_per_k"] == -0.0011
    assert spec.motor["reference_temperature_c"] == 20.0
    for key in ("thermal.ambient_c", "motor.r_temp_coeff_per_k", "motor.psi_f_temp_coeff_per_k"):
        assert key in spec.derived
    assert spec.operating["u_dc_v"] == [280.0, 330.0]
    summary = spec.summary()
    assert summary["thermal"]["initial_c"] == 90.0 and summary["operating"]["ambient_c"] == [0.0, 40.0]


def test_a_file_without_thermal_is_unchanged():
    spec = drive_spec("book")
    assert not spec.thermal and not spec.operating
    assert "thermal" not in spec.summary() and "r_temp_coeff_per_k" not in spec.motor


def test_assembled_part_in_kelvin(tmp_path):
    from pmsmjax.assemble import spec_drive

    path = warm_file(tmp_path, "r_temp_coeff_per_k = 0.004\npsi_f_temp_coeff_per_k = -0.0012\n")
    thermal = spec_drive(drive_spec(path)).thermal
    values = {k: float(np.asarray(getattr(thermal, k))) for k in ("initial_k", "ambient_k", "reference_k")}
    np.testing.assert_allclose(list(values.values()), [363.15, 313.15, 293.15], rtol=1e-6)
    assert float(thermal.r_temp_coeff) == pytest.approx(0.004)
    assert float(thermal.psi_f_temp_coeff) == pytest.approx(-0.0012)
    assert spec_drive(drive_spec("book")).thermal is None


@pytest.mark.parametrize(
    "motor_extra, thermal, words",
    [
        ("r_temp_coeff_per_k = 0.393\n", THERMAL, ["r_temp_coeff_per_k = 0.393", "%/K", "write 0.00393"]),
        ("psi_f_temp_coeff_per_k = -0.11\n", THERMAL, ["psi_f_temp_coeff_per_k", "%/K", "write -0.0011"]),
        ("psi_f_temp_coeff_per_k = 0.001\n", THERMAL, ["psi_f_temp_coeff_per_k", "give a value <= 0"]),
        ("r_temp_coeff_per_k = -0.004\n", THERMAL, ["r_temp_coeff_per_k", "give a value >= 0"]),
        ("", THERMAL.replace("initial_c = 90.0", "initial_c = 363.15"), ["initial_c", "kelvin", "write 90"]),
        ("", THERMAL.replace("r_th_k_per_w = 0.5\n", ""), ["lacks r_th_k_per_w", "K/W"]),
        ("", THERMAL.replace("c_th_j_per_k = 1500.0", "c_th_j_per_k = 0.0"), ["c_th_j_per_k", "above 0"]),
        ("", THERMAL.replace("[20.0, 120.0]", "[120.0, 20.0]"), ["winding_temperature_c", "low <= high"]),
        ("", THERMAL.replace("[280.0, 330.0]", "[0.28, 0.33]"), ["[operating] u_dc_v", "in V"]),
        ("", THERMAL.replace("r_th_k_per_w", "r_th"), ["unknown keys ['r_th']", "r_th_k_per_w"]),
    ],
)
def test_careless_values_refused(tmp_path, motor_extra, thermal, words):
    message = refusal(warm_file(tmp_path, motor_extra, thermal))
    for word in words:
        assert word in message, message


def test_operating_temperatures_need_thermal(tmp_path):
    text = THERMAL.split("[operating]")[1]
    message = refusal(warm_file(tmp_path, thermal="\n[operating]" + text))
    assert "add [thermal]" in message


def test_demo_runs_the_warm_motor(tmp_path, capsys):
    import json

    from pmsmjax.cli import main

    path = warm_file(tmp_path)
    out = tmp_path / "o"
    assert main(["demo", "--motor", str(path), "--duration-s", "0.02", "--load-time-s", "0.01",
                 "--no-figures", "--out", str(out)]) == 0  # fmt: skip
    summary = json.loads((out / "summary.json").read_text())
    thermal = summary["drive"]["thermal"]
    assert thermal["winding_start_c"] == pytest.approx(90.0, abs=1e-3)
    # R and psi_f at 90 degC against their 20 degC data: +27.5 % and -7.7 %
    assert thermal["r_change_pct"] == pytest.approx(100 * 0.00393 * 70, rel=1e-3)
    assert thermal["psi_f_change_pct"] == pytest.approx(-100 * 0.0011 * 70, rel=1e-3)
    assert "winding_temperature_c" in summary["trace_columns"]
    assert "warm motor: winding 90.0" in capsys.readouterr().out
    header = (out / "trace.csv").read_text().splitlines()[0].split(",")
    assert "winding_temperature_c" in header
