"""``pmsmjax export --target c --fixed-point q15 | q31``: the integer controller, compiled with
``cc -std=c99 -Wall -Wextra -Werror`` and driven through ctypes, against the float32 controller and the
simulator on the book drive.

- one step (open loop): every period of a simulator run, the fixed-point controller starts from the float32
  C controller's state (quantised to its words) and gets the same samples (quantised); its duties differ
  from the float32 controller's by at most
  [`duty_error_bound`][pmsmjax.export.fixed_point.duty_error_bound], each quantisation step times the
  gains it passes through. Without the re-synchronisation the integrals of the two controllers drift apart
  by the accumulated input rounding (no feedback in open loop), which says nothing about the arithmetic.
- closed loop: the plant stepped in JAX under the fixed-point duties. The speed PI's integral drives the
  quantised speed error to zero, so the speeds differ by at most the reference's and the measurement's
  half LSBs, ``q w_b``; the q-axis reference then differs by ``(kp + B_a) q w_b`` and the currents by that
  plus twice the one-step current error (the current loop's peak closed-loop gain is about 1); both plus
  the float32 controller's own tolerance against the simulator (``TOL`` of ``test_c_controller``). The
  duties are not compared in closed loop: the rotor angles drift apart by the integral of the speed
  difference, which rotates the abc duties without any error in dq.
"""

import ctypes
import math
import subprocess

import jax
import numpy as np
import pytest
from test_c_controller import CC, TOL, CController, export, float32_drive

from pmsmjax.cli import main

needs_cc = pytest.mark.skipif(CC is None, reason="no C compiler (cc or gcc) on PATH to build the C target")
STRICT = ["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror"]


class FixedController:
    """The fixed-point C target compiled into a shared library; SI in, duties 0..1 out (quantised and
    dequantised here as the header states)."""

    def __init__(self, folder, variant: str, scaling):
        self.W = 16 if variant == "q15" else 32
        self.F = scaling.fmt.signal_frac
        self.IF = scaling.fmt.integral_frac
        self.sc = scaling
        word = ctypes.c_int16 if self.W == 16 else ctypes.c_int32
        acc = ctypes.c_int32 if self.W == 16 else ctypes.c_int64
        names = ("i_a", "i_b", "i_c", "theta_e", "omega_m", "speed_ref", "u_dc")
        self.Inputs = type("Inputs", (ctypes.Structure,), {"_fields_": [(n, word) for n in names]})
        Outputs = type(
            "Outputs", (ctypes.Structure,), {"_fields_": [(n, word) for n in ("d_a", "d_b", "d_c")]}
        )
        fields = [(n, acc) for n in ("speed_integral", "current_integral_d", "current_integral_q")]
        fields += [(n, word) for n in ("u_d_prev", "u_q_prev", "iq_ref")] + [("counter", ctypes.c_int)]
        State = type("State", (ctypes.Structure,), {"_fields_": fields})
        lib = folder / f"pmsm_{variant}.so"
        source = folder / f"pmsm_controller_{variant}.c"
        built = subprocess.run(
            [CC, *STRICT, "-shared", "-fPIC", "-o", str(lib), str(source)], capture_output=True, text=True
        )
        assert built.returncode == 0, f"the fixed-point target does not compile:\n{built.stderr}"
        self.lib = ctypes.CDLL(str(lib))
        self.state, self.out = State(), Outputs()
        getattr(self.lib, f"pmsm_{variant}_init")(ctypes.byref(self.state))
        self._step = getattr(self.lib, f"pmsm_{variant}_step")

    def word(self, x_pu: float, frac: int | None = None) -> int:
        bits = self.F if frac is None else frac
        top = 2 ** (self.W - 1) if frac is None else 2 ** (2 * self.W - 1)
        return int(min(max(round(float(x_pu) * 2.0**bits), -top), top - 1))

    def step(self, i_abc, theta_e, omega_m, speed_ref, u_dc) -> np.ndarray:
        sc, W = self.sc, self.W
        wrapped = (float(theta_e) + math.pi) % (2 * math.pi) - math.pi
        angle = (round(wrapped / math.pi * 2 ** (W - 1)) + 2 ** (W - 1)) % 2**W - 2 ** (W - 1)
        words = [self.word(i / sc.current_base_a) for i in i_abc]
        words += [angle, self.word(omega_m / sc.speed_base_rad_s), self.word(speed_ref / sc.speed_base_rad_s)]
        words.append(self.word(u_dc / sc.voltage_base_v))
        self._step(ctypes.byref(self.state), ctypes.byref(self.Inputs(*words)), ctypes.byref(self.out))
        return np.array([self.out.d_a, self.out.d_b, self.out.d_c], np.float64) / 2.0 ** (W - 1)

    def load(self, float_state) -> None:
        """Set the state to the float32 C controller's, quantised to the words."""
        sc, s = self.sc, self.state
        s.speed_integral = self.word(float_state.speed_integral / sc.current_base_a, self.IF)
        s.current_integral_d = self.word(float_state.current_integral_d / sc.voltage_base_v, self.IF)
        s.current_integral_q = self.word(float_state.current_integral_q / sc.voltage_base_v, self.IF)
        s.u_d_prev = self.word(float_state.u_d_prev / sc.voltage_base_v)
        s.u_q_prev = self.word(float_state.u_q_prev / sc.voltage_base_v)
        s.iq_ref = self.word(float_state.iq_ref / sc.current_base_a)
        s.counter = float_state.counter

    def u_dq(self) -> tuple[float, float]:
        """The last dq voltage command, V."""
        scale = self.sc.voltage_base_v / 2.0**self.F
        return self.state.u_d_prev * scale, self.state.u_q_prev * scale


def scaling_of(drive, variant):
    from pmsmjax.export.description import describe
    from pmsmjax.export.fixed_point import fixed_scaling

    d = describe(drive, "book")
    return d, fixed_scaling(d, float(drive.bridge.u_dc), variant)


@pytest.fixture(scope="module")
def book_run(tmp_path_factory):
    """The book drive (float32), its simulator run, and the float32 C controller's folder."""
    from pmsmjax.simulate import period_inputs, simulate

    root = tmp_path_factory.mktemp("fixed")
    drive, scenario = float32_drive("book")
    with jax.enable_x64(False):
        trace = simulate(drive, scenario).to_numpy()
        speed_ref = np.asarray(period_inputs(scenario, drive.Ts).speed_ref)
    return root, drive, scenario, trace, speed_ref, export(root / "float", "--motor", "book")


def export_fixed(root, variant):
    out = root / variant
    assert main(["export", "--motor", "book", "--fixed-point", variant, "--out", str(out)]) == 0
    return out


def operating_range(drive, trace, scaling):
    """The run's largest current and speed, pu (the bound's operating range)."""
    return (
        float(np.abs(trace.i_abc).max()) / scaling.current_base_a,
        float(np.abs(trace.omega_m).max()) / scaling.speed_base_rad_s,
    )


@needs_cc
@pytest.mark.parametrize("variant", ["q15", "q31"])
def test_one_step_duties_within_the_quantisation_bound(book_run, variant):
    from pmsmjax.export.fixed_point import duty_error_bound

    root, drive, _, trace, speed_ref, float_folder = book_run
    d, sc = scaling_of(drive, variant)
    fixed = FixedController(export_fixed(root, variant), variant, sc)
    reference = CController(float_folder)
    u_dc = float(np.float32(drive.bridge.u_dc))
    worst = 0.0
    for k in range(len(trace.t)):
        fixed.load(reference.state)
        args = (trace.i_abc[k], trace.theta_e[k], trace.omega_m[k], speed_ref[k], u_dc)
        worst = max(worst, float(np.abs(fixed.step(*args) - reference.step(*args)).max()))
    bound = duty_error_bound(d, sc, *operating_range(drive, trace, sc))["duty"]
    print(f"\nbook {variant} one step, max |duty - float32 duty| {worst:.3g} (bound {bound:.3g})")
    assert worst <= bound
    assert worst > 0.0  # the comparison saw the quantisation


def fixed_closed_loop(drive, scenario, c: FixedController) -> dict:
    """The plant stepped in JAX (float32) under the fixed-point duties, one period late."""
    import equinox as eqx
    import jax.numpy as jnp

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
        u_dc = float(np.float32(drive.bridge.u_dc))
        n = len(speed_ref)
        rec = {"omega_m": np.zeros(n), "i_dq": np.zeros((n, 2)), "u_dq": np.zeros((n, 2))}
        pending = jnp.full(3, 0.5, jnp.float32)
        for k in range(n):
            omega = np.float32(ms.omega_m)
            new = jnp.asarray(c.step(i_abc, np.float32(ms.theta_e), omega, speed_ref[k], u_dc), jnp.float32)
            rec["omega_m"][k], rec["i_dq"][k], rec["u_dq"][k] = omega, i_dq, c.u_dq()
            ms, i_abc, i_dq = plant(drive, ms, pending, load[k])
            i_abc, i_dq, pending = np.asarray(i_abc), np.asarray(i_dq), new
    return rec


@needs_cc
@pytest.mark.parametrize("variant", ["q15", "q31"])
def test_closed_loop_on_the_fixed_point_controller(book_run, variant):
    from pmsmjax.export.fixed_point import duty_error_bound

    root, drive, scenario, trace, _, _ = book_run
    d, sc = scaling_of(drive, variant)
    rec = fixed_closed_loop(drive, scenario, FixedController(export_fixed(root, variant), variant, sc))
    diff = {
        "omega_m_rad_s": float(np.abs(rec["omega_m"] - trace.omega_m).max()),
        "i_dq_A": float(np.abs(rec["i_dq"] - trace.i_dq).max()),
        "u_dq_V": float(np.abs(rec["u_dq"] - trace.u_dq_ref).max()),
    }
    q = 2.0**-sc.fmt.signal_frac
    speed = float(np.abs(trace.omega_m).max())
    d_speed = q * sc.speed_base_rad_s + TOL * speed
    step = duty_error_bound(d, sc, *operating_range(drive, trace, sc))
    d_current = (d.speed_kp + d.speed_active_damping) * d_speed + 2 * step["i_dq"] * sc.current_base_a
    d_current += TOL * d.current_limit_a
    print(
        f"\nbook {variant} closed loop, max |fixed - simulator|: "
        + ", ".join(f"{k} {v:.3g}" for k, v in diff.items())
        + f" (bounds: speed {d_speed:.3g} rad/s, i_dq {d_current:.3g} A)"
    )
    assert diff["omega_m_rad_s"] <= d_speed, diff
    assert diff["i_dq_A"] <= d_current, diff
    assert trace.omega_m[-1] == pytest.approx(1000 * math.pi / 30, rel=0.01)


@needs_cc
def test_the_fixed_point_header_states_bases_formats_and_rounding(tmp_path):
    folder = export_fixed(tmp_path, "q15")
    header = " ".join((folder / "pmsm_controller_q15.h").read_text().replace("\n *", " ").split())
    for text in ("I_b = 15 A", "U_b = U_dc/sqrt(3) = 179.5", "w_b = U_b/(p psi_f)", "Q2.13", "Q0.15 of pi"):
        assert text in header, text
    assert "saturates" in header and "rounding half up" in header
    strict = [*STRICT, "-Wpedantic", "-Wshadow", "-c", "-o", str(tmp_path / "q.o")]
    built = subprocess.run(
        [CC, *strict, str(folder / "pmsm_controller_q15.c")], capture_output=True, text=True
    )
    assert built.returncode == 0, built.stderr


@pytest.mark.parametrize(
    "flags, names",
    [
        (["--fixed-point", "q15", "--target", "odrive"], ["--fixed-point q15", "--target c"]),
        (["--fixed-point", "q31", "--field-weakening"], ["--fixed-point q31", "--field-weakening"]),
        (["--fixed-point", "q15", "--motor", "industrial-5k6w"], ["--fixed-point q15", "dead_time_s"]),
    ],
    ids=["vendor-target", "field-weakening", "dead-time-compensation"],
)
def test_fixed_point_refusals_write_nothing(tmp_path, capsys, flags, names):
    out = tmp_path / "out"
    assert main(["export", *flags, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("pmsmjax export: error: "), err
    for name in names:
        assert name in err, err
    assert not out.exists()
