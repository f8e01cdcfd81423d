"""``pmsmjax export --target c``: the C controller, compiled by the system compiler and driven through
ctypes, is the simulator's controller to float32 rounding.

Two checks per drive, both in float32 (the suite runs float64; the drives here are built and simulated
inside ``jax.enable_x64(False)``, as ``pmsmjax demo`` runs them):

- open loop: the C controller gets, period by period, the samples the simulator's controller got in a
  simulator run (phase currents, angle, speed, speed reference, DC link) and its duties are compared with
  the duties the simulator applied one period later (the computation delay);
- closed loop: the plant is stepped in JAX (the drive's own bridge and machine, ``Bridge.advance``) with
  the C duties, and the whole trace (speed, angle, dq currents, duties) is compared with the simulator's.

The bound, ``TOL = 1e-5`` of each signal's range (duties: of 1; voltages: of U_dc; currents: of the
current limit; speed: of the largest speed), is about 170 float32 epsilons (2^-23 = 1.2e-7): the C
library's ``cosf``/``sinf``/``tanhf`` and XLA's differ by an ulp or so, the Clarke of the sampled phase
currents differs from the simulator's alpha-beta currents by a few ulps, and the PI integrals sum such
differences over thousands of periods. In closed loop the plant states drift apart by as much, and the
current PI turns a current difference into a duty difference: the duties' bound there is
``TOL (1 + kp I_max / U_dc)``. The closed loop is stable, so a float32 difference does not grow: the
measured ones stay within a few hundred epsilons (printed with ``pytest -s``).
"""

import ctypes
import math
import shutil
import subprocess

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from pmsmjax.cli import main

#: Relative bound of every compared signal (module docstring).
TOL = 1e-5
CC = shutil.which("cc") or shutil.which("gcc")
CFLAGS = ["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-shared", "-fPIC"]
needs_cc = pytest.mark.skipif(CC is None, reason="no C compiler (cc or gcc) on PATH to build the C target")


class Inputs(ctypes.Structure):
    _fields_ = [(n, ctypes.c_float) for n in ("i_a", "i_b", "i_c", "theta_e", "omega_m", "speed_ref", "u_dc")]


class Outputs(ctypes.Structure):
    _fields_ = [(n, ctypes.c_float) for n in ("d_a", "d_b", "d_c")]


class State(ctypes.Structure):
    _fields_ = [
        (n, ctypes.c_float)
        for n in (
            "speed_integral",
            "current_integral_d",
            "current_integral_q",
            "fw_delta_id",
            "u_d_prev",
            "u_q_prev",
            "iq_ref",
            "i_d_ref",
        )
    ] + [("counter", ctypes.c_int)]


class CController:
    """The C target of a drive compiled into a shared library, stepped through ctypes."""

    def __init__(self, folder):
        lib = folder / "pmsm_controller.so"
        built = subprocess.run(
            [CC, *CFLAGS, "-o", str(lib), str(folder / "pmsm_controller.c"), "-lm"],
            capture_output=True,
            text=True,
        )
        assert built.returncode == 0, f"the C target does not compile:\n{built.stderr}"
        self.lib = ctypes.CDLL(str(lib))
        self.state, self.out = State(), Outputs()
        self.lib.pmsm_controller_init(ctypes.byref(self.state))

    def step(self, i_abc, theta_e, omega_m, speed_ref, u_dc) -> np.ndarray:
        inputs = Inputs(*(float(x) for x in (*i_abc, theta_e, omega_m, speed_ref, u_dc)))
        self.lib.pmsm_controller_step(ctypes.byref(self.state), ctypes.byref(inputs), ctypes.byref(self.out))
        return np.array([self.out.d_a, self.out.d_b, self.out.d_c], np.float32)


def export(tmp_path, *flags) -> object:
    """Run ``pmsmjax export`` with ``flags`` into a fresh folder; returns the folder."""
    out = tmp_path / "c"
    assert main(["export", "--out", str(out), *map(str, flags)]) == 0
    return out


def float32_drive(motor, field_weakening=False, gains=None, **options):
    """The drive ``pmsmjax export --motor motor`` writes (built as ``pmsmjax demo`` builds it), float32,
    and its scenario."""
    from pmsmjax.assemble import assemble, spec_scenario
    from pmsmjax.io.drive_files import drive_spec
    from tuning.parameters import apply_gains

    spec = drive_spec(motor)
    with jax.enable_x64(False):
        if field_weakening:
            from pmsmjax.presets import field_weakening_block

            options["d_axis"] = field_weakening_block(spec.control["current_bandwidth_rad_s"])
        drive = assemble(spec, "pi", options=options)
        if gains:
            drive = apply_gains(drive, gains)
        return drive, spec_scenario(spec)


def open_loop(drive, scenario, c: CController):
    """The simulator's float32 run and the C controller's duties on its samples: ``(trace, duties (N, 3),
    u_dq (N, 2), i_dq_ref (N, 2), fw_delta_id (N,))``, row k the C controller's output at period k."""
    from pmsmjax.simulate import period_inputs, simulate

    with jax.enable_x64(False):
        trace = simulate(drive, scenario).to_numpy()
        speed_ref = np.asarray(period_inputs(scenario, drive.Ts).speed_ref)
    assert trace.duties.dtype == np.float32
    u_dc = np.float32(drive.bridge.u_dc)
    n = len(trace.t)
    duties, u_dq, i_ref, fw = np.zeros((n, 3)), np.zeros((n, 2)), np.zeros((n, 2)), np.zeros(n)
    for k in range(n):
        duties[k] = c.step(trace.i_abc[k], trace.theta_e[k], trace.omega_m[k], speed_ref[k], u_dc)
        s = c.state
        u_dq[k], i_ref[k], fw[k] = (s.u_d_prev, s.u_q_prev), (s.i_d_ref, s.iq_ref), s.fw_delta_id
    return trace, duties, u_dq, i_ref, fw


def closed_loop(drive, scenario, c: CController) -> dict:
    """The plant stepped in JAX (the drive's bridge and machine, float32) under the C controller's duties,
    applied as the drive applies its controller's (one period late with a computation delay);
    ``{signal: (N, ...)}`` at the period starts, as the simulator's trace has them."""
    import equinox as eqx

    from pmsmjax.simulate import period_inputs

    @eqx.filter_jit
    def plant(drive, ms, duties, load):
        ms, _ = drive.bridge.advance(drive.machine, ms, duties, load, drive.Ts, drive.n_substeps)
        return ms, drive.machine.phase_currents(ms), drive.machine.currents_dq(ms)

    with jax.enable_x64(False):
        xs = period_inputs(scenario, drive.Ts)
        speed_ref, load = np.asarray(xs.speed_ref), np.asarray(xs.load_torque)
        ms = drive.init().machine
        i_abc, i_dq = np.asarray(drive.machine.phase_currents(ms)), np.asarray(drive.machine.currents_dq(ms))
        u_dc = np.float32(drive.bridge.u_dc)
        n = len(speed_ref)
        rec = {
            "omega_m": np.zeros(n),
            "theta_e": np.zeros(n),
            "i_dq": np.zeros((n, 2)),
            "duties": np.zeros((n, 3)),
        }
        pending = jnp.full(3, 0.5, jnp.float32)
        for k in range(n):
            theta, omega = np.float32(ms.theta_e), np.float32(ms.omega_m)
            new = jnp.asarray(c.step(i_abc, theta, omega, speed_ref[k], u_dc))
            applied = pending if drive.computation_delay else new
            rec["omega_m"][k], rec["theta_e"][k], rec["i_dq"][k], rec["duties"][k] = (
                omega,
                theta,
                i_dq,
                applied,
            )
            ms, i_abc, i_dq = plant(drive, ms, applied, load[k])
            i_abc, i_dq, pending = np.asarray(i_abc), np.asarray(i_dq), new
    return rec


def check_open_loop(name, drive, trace, duties, u_dq, i_ref) -> dict:
    """Max differences of the C controller's outputs from the simulator's (open loop), asserted within
    ``TOL`` of each signal's range; returns them."""
    limit, u_dc = float(drive.controller.current_limit), float(drive.bridge.u_dc)
    # with a computation delay the duties computed at t_k are applied from t_(k+1), else from t_k
    applied = (duties[:-1], trace.duties[1:]) if drive.computation_delay else (duties, trace.duties)
    diff = {
        "duties": np.abs(applied[0] - applied[1]).max(),
        "u_dq_V": np.abs(u_dq - trace.u_dq_ref).max(),
        "i_dq_ref_A": np.abs(i_ref - trace.i_dq_ref).max(),
    }
    print(f"\n{name} open loop, max |C - simulator|: " + ", ".join(f"{k} {v:.3g}" for k, v in diff.items()))
    assert diff["duties"] <= TOL, diff
    assert diff["u_dq_V"] <= TOL * u_dc, diff
    assert diff["i_dq_ref_A"] <= TOL * limit, diff
    return diff


def check_closed_loop(name, drive, trace, rec) -> dict:
    """Max differences of the closed-loop trace under the C controller from the simulator's, asserted
    within ``TOL`` of each signal's range; returns them."""
    limit = float(drive.controller.current_limit)
    speed = float(np.abs(trace.omega_m).max())
    diff = {
        "duties": np.abs(rec["duties"] - trace.duties).max(),
        "omega_m_rad_s": np.abs(rec["omega_m"] - trace.omega_m).max(),
        "i_dq_A": np.abs(rec["i_dq"] - trace.i_dq).max(),
        "theta_e_rad": np.abs(rec["theta_e"] - trace.theta_e).max(),
    }
    print(f"\n{name} closed loop, max |C - simulator|: " + ", ".join(f"{k} {v:.3g}" for k, v in diff.items()))
    # in closed loop the two controllers act on plant states TOL apart: a current difference of TOL I_max
    # moves the duty by up to kp TOL I_max / U_dc through the current PI's proportional gain
    c = drive.controller.current
    kp = max(float(c.kp_d), float(c.kp_q))
    assert diff["duties"] <= TOL * (1.0 + kp * limit / float(drive.bridge.u_dc)), diff
    assert diff["omega_m_rad_s"] <= TOL * speed, diff
    assert diff["i_dq_A"] <= TOL * limit, diff
    # the angle: within TOL of a turn plus the float32 spacing of the angle reached
    assert diff["theta_e_rad"] <= TOL * 2 * math.pi + 8 * np.spacing(
        np.float32(np.abs(trace.theta_e).max())
    ), diff
    return diff


@pytest.fixture(scope="module")
def book(tmp_path_factory):
    """The book drive's C target (``pmsmjax export --motor book``), its drive and the open-loop run of the
    book scenario (``pmsmjax demo``'s default: 1000 r/min step, 10 N m at 0.2 s, 0.4 s)."""
    folder = export(tmp_path_factory.mktemp("book"), "--motor", "book")
    drive, scenario = float32_drive("book")
    c = CController(folder)
    return folder, drive, scenario, open_loop(drive, scenario, c)


@needs_cc
def test_book_duties_equal_the_simulators_period_by_period(book):
    folder, drive, _, (trace, duties, u_dq, i_ref, _) = book
    check_open_loop("book", drive, trace, duties, u_dq, i_ref)
    assert trace.omega_m[-1] == pytest.approx(1000 * math.pi / 30, rel=0.01)  # the scenario ran


@needs_cc
def test_book_closed_loop_on_the_c_controller_is_the_simulators_run(book):
    folder, drive, scenario, (trace, *_) = book
    check_closed_loop("book", drive, trace, closed_loop(drive, scenario, CController(folder)))


@needs_cc
def test_field_weakening_drive_with_dead_time_compensation(tmp_path):
    """industrial-5k6w (salient, 540 V, 5 kHz, 2 us dead time compensated) with --field-weakening: MTPA
    and the voltage loop, which takes i_d further down (engaged: its offset reaches below -1 A), over the
    file's scenario (rated speed, then 0.8 x rated torque), open and closed loop."""
    folder = export(tmp_path, "--motor", "industrial-5k6w", "--field-weakening")
    source = (folder / "pmsm_controller.c").read_text()
    assert "PMSM_FW_BANDWIDTH" in source and "PMSM_DT_DEAD_TIME" in source
    drive, scenario = float32_drive("industrial-5k6w", field_weakening=True)
    trace, duties, u_dq, i_ref, fw = open_loop(drive, scenario, CController(folder))
    assert fw.min() < -1.0 and trace.i_dq_ref[:, 0].min() < -5.0  # field weakening and MTPA at work
    check_open_loop("industrial-5k6w --field-weakening", drive, trace, duties, u_dq, i_ref)
    rec = closed_loop(drive, scenario, CController(folder))
    check_closed_loop("industrial-5k6w --field-weakening", drive, trace, rec)


@needs_cc
def test_tuned_gains_are_the_ones_exported_and_run(tmp_path, book):
    """``--gains gains.toml`` (as pmsmjax tune writes it): the C controller carries those gains (float32,
    ``%.9g``) and runs the drive that ``pmsmjax demo --gains`` builds with them."""
    from pmsmjax.export.c_blocks import c_float

    gains = {
        "controller.speed.kp": 0.21,
        "controller.speed.ki": 7.5,
        "controller.current.kp_d": 4.2,
        "controller.current.ki_q": 850.0,
    }
    path = tmp_path / "gains.toml"
    path.write_text(
        "# tuned by pmsmjax tune --control pi\n[gains]\n"
        + "".join(f'"{k}" = {v!r}\n' for k, v in gains.items())
    )
    folder = export(tmp_path, "--motor", "book", "--gains", path)
    text = (folder / "pmsm_controller.c").read_text()
    for name, value in (("SPEED_KP", 0.21), ("SPEED_KI", 7.5), ("KP_D", 4.2), ("KI_Q", 850.0)):
        assert f"PMSM_{name}" in text and f"= {c_float(float(np.float32(value)))};" in text
    assert f"gains: gains file {path}" in " ".join(text.replace("\n *", " ").split())
    drive, scenario = float32_drive("book", gains=gains)
    trace, duties, u_dq, i_ref, _ = open_loop(drive, scenario, CController(folder))
    check_open_loop("book, tuned gains", drive, trace, duties, u_dq, i_ref)
    _, _, _, (design, *_) = book
    assert np.abs(trace.omega_m - design.omega_m).max() > 1.0  # the gains changed the run


@needs_cc
def test_mtpa_speed_divider_no_delay_and_reset_anti_windup(tmp_path):
    """The cascade's other choices, through the Python API: MTPA alone on the salient book motor, the speed
    loop every 3 periods, no computation delay (no prediction, half-period angle advance), the speed
    PI's per-period reset anti-windup, dead-time compensation on the measured current's signs."""
    import equinox as eqx

    from pmsmjax.controllers.dead_time_compensation import DeadTimeCompensation
    from pmsmjax.controllers.mtpa import MTPA
    from pmsmjax.controllers.speed_pi import SpeedLoopGains
    from pmsmjax.export.c_source import write_c
    from pmsmjax.export.description import describe
    from pmsmjax.inverters.voltage_error import VoltageError
    from pmsmjax.presets import book_scenario

    drive, _ = float32_drive("book_salient", d_axis=MTPA(), speed_divider=3, computation_delay=False)
    with jax.enable_x64(False):
        scenario = book_scenario(1000.0, 10.0, 0.1, 0.2)
        s = drive.controller.speed
        drive = eqx.tree_at(
            lambda d: (d.controller.speed, d.controller.dead_time_compensation),
            drive,
            (
                SpeedLoopGains(s.kp, s.ki, s.active_damping, anti_windup="reset"),
                DeadTimeCompensation(VoltageError(1e-6, 0.7, 0.3), current_source="measured"),
            ),
            is_leaf=lambda x: x is None,
        )
    d = describe(drive, "book_salient")
    assert (d.d_axis, d.speed_divider, d.computation_delay, d.speed_anti_windup) == (
        "mtpa",
        3,
        False,
        "reset",
    )
    write_c(d, tmp_path)
    trace, duties, u_dq, i_ref, _ = open_loop(drive, scenario, CController(tmp_path))
    assert trace.i_dq_ref[:, 0].min() < -1.0  # MTPA at work
    check_open_loop("book_salient, MTPA, divider 3, no delay", drive, trace, duties, u_dq, i_ref)
    rec = closed_loop(drive, scenario, CController(tmp_path))
    check_closed_loop("book_salient, MTPA, divider 3, no delay", drive, trace, rec)


def test_float_literals_round_trip_float32():
    from pmsmjax.export.c_blocks import c_float

    assert (c_float(15.0), c_float(0.5), c_float(-3e-7)) == ("15.0f", "0.5f", "-3e-07f")
    values = np.random.default_rng(0).lognormal(0, 8, 200).astype(np.float32)
    assert all(np.float32(float(c_float(float(v))[:-1])) == v for v in values)


@needs_cc
@pytest.mark.parametrize(
    "flags", [[], ["--field-weakening", "--motor", "industrial-5k6w"]], ids=["book", "fw"]
)
def test_the_c_target_compiles_under_strict_firmware_warnings(tmp_path, flags):
    """No implicit double arithmetic (a float-only FPU), no conversion or shadowing, ISO C99 only."""
    folder = export(tmp_path, *flags)
    strict = ["-std=c99", "-O2", "-Wall", "-Wextra", "-Wpedantic", "-Wdouble-promotion", "-Wconversion"]
    built = subprocess.run(
        [
            CC,
            *strict,
            "-Wshadow",
            "-Werror",
            "-c",
            str(folder / "pmsm_controller.c"),
            "-o",
            str(tmp_path / "c.o"),
        ],
        capture_output=True,
        text=True,
    )
    assert built.returncode == 0, built.stderr
