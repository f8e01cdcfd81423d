"""The book's PWM comparison (chapter 2): every modulator at one steady operating point, both bridges.

Procedure (all variants at the same operating point, so at equal fundamental voltage up to what the
closed loop needs):

1. The book drive (averaged bridge, SVPWM) runs the book scenario (speed step from rest, load step at
   0.2 s, 0.4 s) to a steady state. Inside the linear range every modulator gives the averaged bridge the
   same period-average voltage, so this state is every variant's starting point.
2. Each variant (modulator x bridge) continues from there at the final speed reference and load for
   ``settle_cycles`` fundamental periods (the switching ripple and any dead-time disturbance settle), then
   ``window_cycles`` are analysed.
3. Within every analysed period the current is sampled ``samples_per_period`` times on a uniform grid
   (from the model's own period-start state and duties, so it is the trajectory the model followed) and
   the phase voltage is rebuilt exactly from the bridge's constant-voltage intervals.
4. Spectra (:mod:`pmsmjax.analysis.spectra`): exact Fourier coefficients of the piecewise-constant voltages,
FFT
   of the current samples; THD up to ``f_max = thd_max_carriers * f_sw``.

Variants: ``<modulator>`` (averaged bridge), ``<modulator>_switching`` (:class:`SwitchingBridge`, no dead
time) and ``<modulator>_switching_deadtime`` (dead time ``dead_time_s``), for the modulators
``sinusoidal``, ``third_harmonic``, ``min_max``, ``svpwm``.
"""

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from pmsmjax.analysis.spectra import piecewise_constant_spectrum, sampled_spectrum, thd
from pmsmjax.analysis.within_period import dense_window
from pmsmjax.checks.validation import ParameterError
from pmsmjax.drive import Drive
from pmsmjax.frames.three_phase import alpha_beta_to_abc, dq_to_abc
from pmsmjax.inverters import (
    SVPWM,
    AveragedBridge,
    MinMaxPWM,
    SinusoidalPWM,
    SwitchingBridge,
    ThirdHarmonicPWM,
)
from pmsmjax.presets.three_phase import book_drive, book_scenario
from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.simulate import period_inputs, simulate
from pmsmjax.units import rpm_to_rad_s

MODULATORS = {
    "sinusoidal": SinusoidalPWM,
    "third_harmonic": ThirdHarmonicPWM,
    "min_max": MinMaxPWM,
    "svpwm": SVPWM,
}


@dataclasses.dataclass(frozen=True)
class CompareSettings:
    """Operating point and analysis sizes.

    - `speed_rpm`, `load_nm`: steady operating point (reached through the book scenario).
    - `dead_time_s`: dead time of the ``_deadtime`` variants, s.
    - `settle_cycles`, `window_cycles`: fundamental periods settled, then analysed.
    - `samples_per_period`: current samples per PWM period.
    - `thd_max_carriers`: THD includes components up to this many times the switching frequency.
    - `modulators`: which modulators; `bridges`: subset of ``("averaged", "switching", "deadtime")``.
    """

    speed_rpm: float = 1000.0
    load_nm: float = 10.0
    dead_time_s: float = 2e-6
    settle_cycles: int = 2
    window_cycles: int = 2
    samples_per_period: int = 32
    thd_max_carriers: float = 4.0
    modulators: tuple[str, ...] = tuple(MODULATORS)
    bridges: tuple[str, ...] = ("averaged", "switching", "deadtime")

    def check(self, Ts: float, pole_pairs: int) -> int:
        """Validate; return the PWM periods per fundamental period (must be whole)."""
        unknown = [m for m in self.modulators if m not in MODULATORS]
        if unknown:
            raise ParameterError(f"unknown modulators {unknown}: choose from {list(MODULATORS)}.")
        bad = [b for b in self.bridges if b not in ("averaged", "switching", "deadtime")]
        if bad:
            raise ParameterError(f"unknown bridges {bad}: choose from averaged, switching, deadtime.")
        if self.speed_rpm <= 0:
            raise ParameterError(f"speed_rpm must be > 0 for a spectrum, got {self.speed_rpm}.")
        f1 = self.speed_rpm / 60.0 * pole_pairs
        per_cycle = 1.0 / (f1 * Ts)
        if abs(per_cycle - round(per_cycle)) > 1e-9 * per_cycle:
            raise ParameterError(
                f"a fundamental period ({1e3 / f1:.6g} ms at {self.speed_rpm} r/min) is not a whole "
                f"number of PWM periods ({Ts * 1e6:g} us): pick f_sw / f_1 an integer (1000 r/min)."
            )
        need = int(np.floor(2 * self.thd_max_carriers)) + 2  # the current's FFT must reach f_max
        if not isinstance(self.samples_per_period, int) or self.samples_per_period < need:
            raise ParameterError(
                f"samples_per_period must be an int >= {need}, got {self.samples_per_period}."
            )
        return int(round(per_cycle))


def steady_state(drive: Drive, settings: CompareSettings):
    """Drive state at the end of the book scenario to the operating point (averaged, SVPWM)."""
    scenario = book_scenario(settings.speed_rpm, settings.load_nm)
    xs = period_inputs(scenario, drive.Ts)
    run = eqx.filter_jit(lambda d, s, x: jax.lax.scan(lambda c, xi: (d.step(c, xi)[0], None), s, x)[0])
    return run(drive, drive.init(), xs)


def run_variant(drive: Drive, start, settings: CompareSettings, per_cycle: int) -> dict:
    """Simulate one variant from ``start`` and return its window's waveforms (NumPy).

    Returns ``t_i (N,)`` s and ``i_abc (N, 3)`` A (uniform samples), ``t_u (K+1,)`` s and ``u_abc (K, 3)``
    V (piecewise-constant phase voltages), ``omega_m`` (mean over the window, rad/s).
    """
    Ts, M = drive.Ts, settings.samples_per_period
    n_settle, n_window = settings.settle_cycles * per_cycle, settings.window_cycles * per_cycle
    scenario = Scenario(
        duration_s=(n_settle + n_window) * Ts,
        speed_ref=Profile.constant(rpm_to_rad_s(settings.speed_rpm)),
        load_torque=Profile.constant(settings.load_nm),
    )
    trace = simulate(drive, scenario, initial_state=start)
    window = jax.tree.map(lambda x: x[n_settle:], trace)
    machine = drive.machine
    dense, t_u, u_ab = dense_window(drive, window, M)
    i_abc = dq_to_abc(jax.vmap(jax.vmap(machine.currents_dq))(dense), dense.theta_e)
    return {
        "t_i": (np.arange(n_window * M) + 1) * Ts / M,
        "i_abc": np.asarray(i_abc).reshape(-1, 3),
        "t_u": t_u,
        "u_abc": np.asarray(alpha_beta_to_abc(jnp.asarray(u_ab))),
        "omega_m": float(np.mean(np.asarray(window.omega_m))),
    }


def analyse(wave: dict, settings: CompareSettings, Ts: float, u_dc: float) -> dict:
    """Spectra and figures of merit of one variant's window."""
    cycles = settings.window_cycles
    window_s = wave["t_u"][-1]
    f_max = settings.thd_max_carriers / Ts
    n_max = int(round(f_max * window_s))
    u_abc = wave["u_abc"]
    u_lines = np.stack([u_abc[:, 0] - u_abc[:, 1], u_abc[:, 1] - u_abc[:, 2], u_abc[:, 2] - u_abc[:, 0]], 1)
    spec_u = piecewise_constant_spectrum(wave["t_u"], u_abc, cycles, n_max)
    spec_ll = piecewise_constant_spectrum(wave["t_u"], u_lines, cycles, n_max)
    spec_i = sampled_spectrum(wave["i_abc"], window_s, cycles, n_max)
    mean = lambda x: float(np.mean(x))
    return {
        "fundamental_phase_voltage_v": mean(spec_u.fundamental),
        "fundamental_line_voltage_v": mean(spec_ll.fundamental),
        "fundamental_current_a": mean(spec_i.fundamental),
        "voltage_thd_pct": 100.0 * mean(thd(spec_u, f_max)),
        "line_voltage_thd_pct": 100.0 * mean(thd(spec_ll, f_max)),
        "current_thd_pct": 100.0 * mean(thd(spec_i, f_max)),
        "modulation_index": mean(spec_u.fundamental) / (0.5 * u_dc),
        "spectra": {"phase_voltage": spec_u, "line_voltage": spec_ll, "current": spec_i},
    }


def compare(settings: CompareSettings = CompareSettings(), base: Drive | None = None, progress=None) -> dict:
    """Run every variant; return a dict with ``settings``, ``entries`` (name -> figures), ``waves`` and
    ``spectra`` (name -> the :func:`run_variant` waveforms and the :class:`pmsmjax.analysis.spectra.Spectrum`
    s).

    `base`: the drive to compare on (default: the book drive); `progress`: optional callable taking a line.
    """
    base = book_drive() if base is None else base
    per_cycle = settings.check(base.Ts, base.machine.motor.pole_pairs)
    u_dc = float(base.bridge.u_dc)
    start = steady_state(base, settings)
    reached = float(np.asarray(start.machine.omega_m)) / rpm_to_rad_s(1.0)
    if abs(reached - settings.speed_rpm) > 0.02 * abs(settings.speed_rpm):
        # A drive that did not reach the point runs saturated: its spectra would compare nothing.
        raise ParameterError(
            f"the drive reached {reached:.0f} r/min, not the {settings.speed_rpm:g} r/min asked for, at "
            f"{settings.load_nm:g} N m (voltage or current limit): pick an operating point inside its limits."
        )
    sinusoidal_limit = float(SinusoidalPWM().linear_limit(u_dc))
    entries, waves, spectra = {}, {}, {}
    bridges = {
        "averaged": ("", AveragedBridge(u_dc)),
        "switching": ("_switching", SwitchingBridge(u_dc)),
        "deadtime": ("_switching_deadtime", SwitchingBridge(u_dc, dead_time=settings.dead_time_s)),
    }
    for mod_name in settings.modulators:
        modulator = MODULATORS[mod_name]()
        for bridge_key in settings.bridges:
            suffix, bridge = bridges[bridge_key]
            name = mod_name + suffix
            drive = eqx.tree_at(lambda d: (d.modulator, d.bridge), base, (modulator, bridge))
            wave = run_variant(drive, start, settings, per_cycle)
            figures = analyse(wave, settings, base.Ts, u_dc)
            spectra[name] = figures.pop("spectra")
            limit = float(modulator.linear_limit(u_dc))
            entries[name] = {
                "modulator": mod_name,
                "bridge": "averaged" if bridge_key == "averaged" else "switching",
                "dead_time_s": settings.dead_time_s if bridge_key == "deadtime" else 0.0,
                "linear_limit_v": limit,
                "dc_bus_utilisation_vs_sinusoidal": limit / sinusoidal_limit,
                **figures,
                "speed_rpm": wave.pop("omega_m") * 60.0 / (2.0 * np.pi),
            }
            waves[name] = wave
            if progress:
                e = entries[name]
                progress(
                    f"{name:32s} U1 {e['fundamental_phase_voltage_v']:7.2f} V  THD u "
                    f"{e['voltage_thd_pct']:6.2f} %  THD i {e['current_thd_pct']:6.3f} %"
                )
    return {
        "settings": {
            **dataclasses.asdict(settings),
            "u_dc_v": u_dc,
            "Ts_s": base.Ts,
            "thd_max_frequency_hz": settings.thd_max_carriers / base.Ts,
            "thd_definition": "sqrt(sum of squared peak amplitudes of every Fourier component of the window "
            "but DC and the fundamental, up to thd_max_frequency_hz) / fundamental",
        },
        "entries": entries,
        "waves": waves,
        "spectra": spectra,
    }
