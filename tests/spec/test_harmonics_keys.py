"""The drive file's ``[harmonics]`` table: read, reported in the spec's summary, built into the plant by
the assembler (the dq and flux-map plants), and refused in one line naming the key, the row and the fix."""

import numpy as np
import pytest

from pmsmjax.assemble import assemble
from pmsmjax.io.drive_files import drive_spec
from pmsmjax.machines.harmonics import MagnetHarmonics
from pmsmjax.spec.validation import ParameterError

MOTOR = """[motor]
R = 0.958
L_d = 0.00525
L_q = 0.00525
psi_f = 0.1827
pole_pairs = 4
J = 0.003
B = 0.008
[ratings]
rated_speed_rpm = 1000.0
rated_torque_nm = 10.0
max_current_a = 15.0
"""
TABLE = """[harmonics]
flux = [[5, 0.0019, 0.4], [7, 0.0009, -1.1]]
cogging = [[6, 0.045, 0.3], [12, 0.018, -0.8]]
"""


def _spec(tmp_path, harmonics: str, motor: str = MOTOR):
    path = tmp_path / "drive.toml"
    path.write_text(motor + harmonics)
    return drive_spec(path)


def test_harmonics_are_read_reported_and_built(tmp_path):
    spec = _spec(tmp_path, TABLE)
    assert spec.harmonics["flux"] == ((5, 0.0019, 0.4), (7, 0.0009, -1.1))
    assert spec.summary()["harmonics"]["cogging"] == ((6, 0.045, 0.3), (12, 0.018, -0.8))
    h = assemble(spec).machine.harmonics
    assert isinstance(h, MagnetHarmonics)
    assert h.flux_orders == (5, 7) and h.cogging_orders == (6, 12)
    np.testing.assert_allclose(np.asarray(h.cogging_amplitude), [0.045, 0.018])
    # without the table: no harmonics, the plant as before
    assert assemble(_spec(tmp_path, "")).machine.harmonics is None
    assert "harmonics" not in _spec(tmp_path, "").summary()


def test_flux_map_plant_takes_the_harmonics(tmp_path):
    from pmsmjax.io.drive_files import preset_path

    preset = preset_path("saturated-ipm").read_text()
    map_file = preset_path("saturated-ipm").parent / "saturated_ipm_map.csv"
    text = preset.replace('flux_map = "saturated_ipm_map.csv"', f'flux_map = "{map_file}"')
    spec = _spec(tmp_path, "\n" + TABLE, motor=text)
    machine = assemble(spec).machine
    assert type(machine).__name__ == "PMSMFluxMapdq"
    assert machine.harmonics.flux_orders == (5, 7)


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ("flux = [[9, 0.001, 0.0]]", r"\[harmonics\] flux\[0\] order 9 is triplen.*drop the row"),
        ("flux = [[1, 0.001, 0.0]]", r"order 1 is the fundamental"),
        ("cogging = [[6.5, 0.01, 0.0]]", r"cogging\[0\] order 6.5 must be a whole number"),
        ("cogging = [[0, 0.01, 0.0]]", r"order 0 must be a whole number >= 1"),
        ("cogging = [[6, 0.01]]", r"cogging\[0\] = \[6, 0.01\]: give three finite numbers"),
        ("cogging = [6, 0.01, 0.3]", r"must be a list of \[order, amplitude \(N m\), phase \(rad\)\] rows"),
        ("flux = [[5, 0.05, 0.0]]", r"flux order 5 amplitude 0.05 Wb is above 20 % of psi_f .*unit slip"),
        ("cogging = [[6, 45.0, 0.0]]", r"cogging order 6 amplitude 45 N m is above the rated torque"),
        ("cogging = [[6, -0.1, 0.0]]", r"must be >= 0: add pi to the phase"),
        ("cogging = [[6, 0.1, 30.0]]", r"phase 30 is beyond 2 pi: it looks like degrees: write 0.523599"),
        ("cogging = [[6, 0.1, 0.0], [6, 0.1, 1.0]]", r"order 6 is given twice"),
        ("ripple = [[6, 0.1, 0.0]]", r"unknown keys \['ripple'\] in \[harmonics\]"),
    ],
)
def test_harmonics_refusals_name_the_key_and_the_fix(tmp_path, table, message):
    with pytest.raises(ParameterError, match=message) as err:
        _spec(tmp_path, "[harmonics]\n" + table + "\n")
    assert "\n" not in str(err.value)


def test_trust_units_lifts_the_amplitude_limits(tmp_path):
    motor = MOTOR.replace("B = 0.008\n", "B = 0.008\ntrust_units = true\n")
    spec = _spec(tmp_path, "[harmonics]\nflux = [[5, 0.05, 0.0]]\n", motor=motor)
    assert spec.harmonics["flux"] == ((5, 0.05, 0.0),)


def test_a_multiphase_motor_refuses_harmonics(tmp_path):
    six = MOTOR.replace("B = 0.008\n", "B = 0.008\nn_phases = 6\nL_ls = 0.0005\n")
    with pytest.raises(ParameterError, match=r"\[harmonics\] is modelled for three-phase motors"):
        path = tmp_path / "six.toml"
        path.write_text(six + TABLE)
        drive_spec(path, n_phases=6)
