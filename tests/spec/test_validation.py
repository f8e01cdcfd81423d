"""Input validation: bad concrete input raises ParameterError naming the field and the fix, before compiling.

Every check is exercised with a value on the wrong side of its limit and the message is matched against the
field name (and, where the message promises one, the fix). Checks on ``simulate`` inputs are shown to run
before anything is traced or compiled by replacing the compiled engine with a tripwire. The complementary
contract is tested too: under ``jax.jit``/``jax.vmap`` the values are tracers and the checks stand aside.
"""

import math
import re
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import pmsmjax
from pmsmjax import ParameterError, Profile, Scenario, presets, stack_scenarios
from pmsmjax.controllers import FOC, current_loop_imc, speed_loop_active_damping
from pmsmjax.inverters import AveragedBridge
from pmsmjax.machines import PMSMParameters
from pmsmjax.simulate import check_simulation

SIM_MODULE = sys.modules["pmsmjax.simulate"]

BOOK = dict(R=0.958, L_d=5.25e-3, L_q=5.25e-3, psi_f=0.1827, J=0.003, B=0.008, pole_pairs=4)

# Field -> the label its message starts with (the field name and its meaning).
LABELS = {
    "R": "R (stator resistance)",
    "L_d": "L_d (d-axis inductance)",
    "L_q": "L_q (q-axis inductance)",
    "J": "J (inertia)",
    "psi_f": "psi_f (PM flux linkage)",
    "B": "B (viscous friction)",
}


def motor(**changes) -> PMSMParameters:
    return PMSMParameters(**{**BOOK, **changes})


@pytest.fixture
def no_compile(monkeypatch):
    """Replace the jit-compiled simulation engine by a tripwire: a check that fires later would trip it."""

    def tripwire(*args, **kwargs):
        raise AssertionError("simulate reached the compiled engine; the input check must come first")

    monkeypatch.setattr(SIM_MODULE, "_simulate", tripwire)


# --- motor parameters ----------------------------------------------------------------------------------


@pytest.mark.parametrize("field", ["R", "L_d", "L_q", "J"])
@pytest.mark.parametrize("value", [0.0, -1e-3])
def test_nonpositive_motor_parameter(field, value):
    with pytest.raises(
        ParameterError, match=re.escape(LABELS[field]) + r" must be > 0.*(strictly positive|henry)"
    ):
        motor(**{field: value})


@pytest.mark.parametrize("field", ["R", "L_d", "L_q", "J", "psi_f", "B"])
@pytest.mark.parametrize("value", [math.nan, math.inf])
def test_nonfinite_motor_parameter(field, value):
    with pytest.raises(ParameterError, match=re.escape(LABELS[field]) + r" must be finite.*replace NaN/inf"):
        motor(**{field: value})


@pytest.mark.parametrize("field", ["psi_f", "B"])
def test_negative_flux_or_friction(field):
    with pytest.raises(ParameterError, match=re.escape(LABELS[field]) + r" must be >= 0.*give a value >= 0"):
        motor(**{field: -0.01})
    # Zero is physical for both (no magnet: reluctance machine; no friction).
    assert float(getattr(motor(**{field: 0.0}), field)) == 0.0


def test_inductance_message_suggests_henry():
    with pytest.raises(ParameterError, match=r"L_d .*henry \(mH \* 1e-3\)"):
        motor(L_d=-5.25)


@pytest.mark.parametrize("pole_pairs", [4.0, "4", 0, -2, None])
def test_pole_pairs_must_be_positive_int(pole_pairs):
    with pytest.raises(ParameterError, match=r"pole_pairs must be a positive integer.*as an int"):
        motor(pole_pairs=pole_pairs)


def test_array_parameter_with_one_bad_element():
    """A batch of motors (one per row) is rejected if any row is non-physical, naming the field."""
    with pytest.raises(ParameterError, match=r"J \(inertia\) must be > 0, got -0\.001"):
        motor(J=np.array([0.003, -0.001, 0.004]))


# --- controller, drive, bridge ---------------------------------------------------------------------------


@pytest.mark.parametrize("limit", [0.0, -15.0, math.nan])
def test_current_limit_must_be_positive(limit):
    with pytest.raises(ParameterError, match=r"current_limit must be (> 0|finite)"):
        presets.book_drive(current_limit=limit)


@pytest.mark.parametrize("Ts", [0.0, -1e-4])
def test_control_period_must_be_positive(Ts):
    with pytest.raises(ParameterError, match=r"Drive\.Ts \(control period\) must be > 0"):
        presets.book_drive(Ts=Ts)


@pytest.mark.parametrize("n", [0, -3, 2.5])
def test_n_substeps_must_be_int_at_least_one(n):
    with pytest.raises(ParameterError, match=r"Drive\.n_substeps must be an int >= 1"):
        presets.book_drive(n_substeps=n)


@pytest.mark.parametrize("divider", [0, 1.5])
def test_speed_divider_must_be_positive_int(divider):
    with pytest.raises(ParameterError, match=r"speed_divider must be an int >= 1.*control periods"):
        presets.book_drive(speed_divider=divider)


def test_controller_mode_is_checked():
    m = motor()
    with pytest.raises(ParameterError, match=r"mode must be 'speed' or 'current'"):
        FOC(m, speed_loop_active_damping(m), current_loop_imc(m), 15.0, mode="torque")


@pytest.mark.parametrize("u_dc", [0.0, -311.0])
def test_dc_link_must_be_positive(u_dc):
    with pytest.raises(ParameterError, match=r"u_dc \(DC-link voltage\) must be > 0"):
        AveragedBridge(u_dc)


@pytest.mark.parametrize("design", [current_loop_imc, speed_loop_active_damping])
def test_bandwidth_must_be_positive(design):
    with pytest.raises(ParameterError, match=r"bandwidth .* must be > 0"):
        design(motor(), 0.0)


# --- simulate inputs: checked before compiling -----------------------------------------------------------


def test_tripwire_catches_a_compile(no_compile):
    """The fixture works: a valid input reaches the engine and trips it."""
    with pytest.raises(AssertionError, match="compiled engine"):
        pmsmjax.simulate(presets.book_drive(), Scenario(0.01))


def test_substep_too_long_names_n_substeps_and_its_fix_works(no_compile):
    """Ts = 1 ms with one RK4 step at 3000 r/min (omega_e = 1257 rad/s): the message gives the cure."""
    drive = presets.book_drive(Ts=1e-3, n_substeps=1)
    scenario = presets.book_scenario(speed_rpm=3000.0, duration_s=0.1, load_time_s=0.05)
    with pytest.raises(ParameterError, match=r"sub-step .* too long.*set Drive\.n_substeps >= \d+") as err:
        pmsmjax.simulate(drive, scenario)
    need = int(re.search(r"n_substeps >= (\d+)", str(err.value)).group(1))
    # Independent bound: RK4 sub-step <= 0.5 / max(R/L, p omega_max), omega_max = 1.5 * 3000 r/min + 1 rad/s.
    omega_e_max = 4 * (1.5 * 3000 * 2 * math.pi / 60 + 1.0)
    assert need == math.ceil(1e-3 * omega_e_max / 0.5)
    check_simulation(presets.book_drive(Ts=1e-3, n_substeps=need), scenario)  # the suggested fix passes
    with pytest.raises(ParameterError, match="n_substeps"):
        check_simulation(presets.book_drive(Ts=1e-3, n_substeps=need - 1), scenario)


def test_duration_not_multiple_of_Ts(no_compile):
    drive = presets.book_drive()  # Ts = 1e-4 s
    with pytest.raises(
        ParameterError, match=r"duration_s = 0\.01005 s is not a whole number.*multiple of Ts"
    ):
        pmsmjax.simulate(drive, Scenario(0.01005))
    check_simulation(drive, Scenario(0.0101))  # 101 periods: fine (float rounding of 0.0101/1e-4 tolerated)


@pytest.mark.parametrize("decimate", [3, 0, -1, 2.0])
def test_decimate_must_divide_period_count(no_compile, decimate):
    with pytest.raises(
        ParameterError, match=rf"decimate = {re.escape(repr(decimate))} must be a positive int"
    ):
        pmsmjax.simulate(presets.book_drive(), Scenario(0.01), decimate=decimate)


def test_scenario_duration_must_be_positive():
    with pytest.raises(ParameterError, match=r"Scenario\.duration_s must be > 0"):
        Scenario(0.0)


# --- profiles and scenarios ------------------------------------------------------------------------------


def test_profile_decreasing_times():
    with pytest.raises(ParameterError, match=r"Profile\.times must be non-decreasing: sort the breakpoints"):
        Profile([0.0, 0.2, 0.1], [0.0, 1.0, 2.0], [0.0, 0.0, 0.0])
    # Equal times are allowed (an instantaneous jump).
    Profile([0.0, 0.1, 0.1], [0.0, 1.0, 2.0], [0.0, 0.0, 0.0])


@pytest.mark.parametrize(
    "times, values, linear",
    [([0.0, 0.1], [1.0], [0.0, 0.0]), ([0.0, 0.1], [1.0, 2.0], [0.0]), (0.0, 1.0, 0.0)],
)
def test_profile_shapes_must_match(times, values, linear):
    with pytest.raises(
        ParameterError, match=r"Profile times, values and linear must have the same shape \(K,\)"
    ):
        Profile(times, values, linear)


def test_profile_values_must_be_finite():
    with pytest.raises(ParameterError, match=r"Profile\.values must be finite"):
        Profile.piecewise([0.0, 0.1], [0.0, math.nan])
    with pytest.raises(ParameterError, match=r"Profile\.times must be finite"):
        Profile.piecewise([0.0, math.inf], [0.0, 1.0])


def test_profile_interpolation_name():
    with pytest.raises(ParameterError, match=r"interpolation must be 'hold' or 'linear'"):
        Profile.piecewise([0.0, 0.1], [0.0, 1.0], interpolation="cubic")


def test_stack_scenarios_needs_equal_durations():
    with pytest.raises(ParameterError, match=r"must share duration_s"):
        stack_scenarios([Scenario(0.1), Scenario(0.2)])
    with pytest.raises(ParameterError, match=r"at least one scenario"):
        stack_scenarios([])


# --- motor files -----------------------------------------------------------------------------------------

GOOD_TOML = """R = 0.958
L_d = 5.25e-3
L_q = 5.25e-3
psi_f = 0.1827
pole_pairs = 4
J = 0.003
B = 0.008
"""


def write(tmp_path, text, name="motor.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_load_motor_good_file_and_table(tmp_path):
    """Positive control: the same file parses flat and under [motor], equal to the book preset."""
    book = presets.book_motor()
    for text in (GOOD_TOML, "[motor]\n" + GOOD_TOML):
        m = presets.load_motor(write(tmp_path, text))
        for f in ("R", "L_d", "L_q", "psi_f", "J", "B"):
            assert float(getattr(m, f)) == float(getattr(book, f))
        assert m.pole_pairs == 4


def test_load_motor_missing_key(tmp_path):
    path = write(tmp_path, GOOD_TOML.replace("psi_f = 0.1827\n", ""))
    with pytest.raises(
        ParameterError, match=r"lacks psi_f in \[motor\]: it needs R, L_d, L_q, psi_f, pole_pairs, J, B"
    ):
        presets.load_motor(path)


def test_load_motor_unknown_key(tmp_path):
    path = write(tmp_path, GOOD_TOML + "Ld = 5e-3\n")
    with pytest.raises(
        ParameterError, match=r"unknown keys \['Ld'\] in \[motor\] \('Ld' looks like 'L_d'\); allowed: R, L_d"
    ):
        presets.load_motor(path)


@pytest.mark.parametrize("value", ["4.0", '"4"'])
def test_load_motor_non_int_pole_pairs(tmp_path, value):
    path = write(tmp_path, GOOD_TOML.replace("pole_pairs = 4", f"pole_pairs = {value}"))
    with pytest.raises(ParameterError, match=r"pole_pairs must be a whole number >= 1"):
        presets.load_motor(path)


def test_load_motor_non_number_and_nonphysical(tmp_path):
    with pytest.raises(ParameterError, match=r"\[motor\] R must be a finite number \(ohm\)"):
        presets.load_motor(write(tmp_path, GOOD_TOML.replace("R = 0.958", 'R = "low"')))
    with pytest.raises(ParameterError, match=r"\[motor\] J = -0.003 kg m\^2: give a value > 0"):
        presets.load_motor(write(tmp_path, GOOD_TOML.replace("J = 0.003", "J = -0.003")))


def test_load_motor_bad_toml(tmp_path):
    with pytest.raises(ParameterError, match=r"not valid TOML"):
        presets.load_motor(write(tmp_path, "R = = 1\n"))


def test_load_motor_missing_path(tmp_path):
    with pytest.raises(
        ParameterError, match=r"neither a preset \(book, book_salient, .*servo-400w.*\) nor a drive file"
    ):
        presets.load_motor(tmp_path / "nope.toml")


# --- traced values: the checks stand aside ----------------------------------------------------------------


def test_construction_under_vmap_and_jit_skips_checks():
    """Under vmap/jit the values are tracers: no check runs, even for values a concrete call would reject."""

    def build(R, J):
        return PMSMParameters(R=R, L_d=5.25e-3, L_q=5.25e-3, psi_f=0.1827, J=J, B=0.008).J

    bad = jnp.array([-1.0, jnp.nan])
    np.testing.assert_array_equal(np.isnan(jax.vmap(build)(bad, bad)), [False, True])
    assert float(jax.jit(build)(-1.0, -2.0)) == -2.0

    def profile(times):
        return Profile(times, jnp.zeros(3), jnp.zeros(3)).times

    decreasing = jnp.array([[0.0, 0.2, 0.1], [0.0, 0.1, 0.2]])
    assert jax.vmap(profile)(decreasing).shape == (2, 3)
    assert jax.jit(lambda c: current_loop_imc(motor(), c).kp_q)(-1.0) < 0


def test_simulate_under_jit_with_traced_parameters():
    """jit over J and the reference speed: the checks skip tracers, and the result equals the concrete run."""
    scenario = Scenario(0.005, speed_ref=Profile.constant(50.0))

    def final_speed(J, speed):
        drive = presets.book_drive(motor(J=J))
        return pmsmjax.simulate(drive, Scenario(0.005, speed_ref=Profile.constant(speed))).omega_m[-1]

    traced = float(jax.jit(final_speed)(0.003, 50.0))
    concrete = float(pmsmjax.simulate(presets.book_drive(motor()), scenario).omega_m[-1])
    assert traced > 0.5
    assert traced == pytest.approx(concrete, rel=1e-12)
