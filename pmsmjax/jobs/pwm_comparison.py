"""The PWM comparison for any phase count: every modulator of a drive at one steady operating point, with the
averaged and the switching-resolved bridge (the book, ch. 2: three phases; chapter 8: six; chapter 10:
five).

Procedure (all variants at the same operating point, so at equal fundamental voltage up to what the
closed loop needs):

1. The base drive ([`PhaseCount.base_drive`][pmsmjax.jobs.pwm_comparison.PhaseCount]) runs the book
   scenario (speed step from rest, load step at 0.2 s, 0.4 s) to a steady state. Three phases: the book drive
   (SVPWM, averaged bridge). Six and five phases: **conventional** control (dq current loops only: the second
   plane's voltage reference is zero and nothing corrects its currents, so each modulator's own second-plane
   voltage shows in the currents; a second-plane loop would fight the methods that cannot apply one) with
   four-vector (near-four-vector) SVPWM on the averaged bridge. Inside the linear range every modulator gives
   the averaged bridge the same period-average voltage, so this state is every variant's starting point.
2. Each variant (modulator x bridge) continues from there at the final speed reference and load for
   ``settle_cycles`` fundamental periods (the switching ripple and any dead-time disturbance settle), then
   ``window_cycles`` are analysed.
3. Within every analysed period the phase currents are sampled ``samples_per_period`` times on a uniform
   grid ([`pmsmjax.analysis.within_period.dense_window`][pmsmjax.analysis.within_period.dense_window]: from
   the model's own period-start state and duties, so it is the trajectory the model followed) and the phase
   voltages are rebuilt exactly from the bridge's constant-voltage intervals.
4. Spectra ([`pmsmjax.analysis.spectra`][pmsmjax.analysis.spectra]): exact Fourier coefficients of the
   piecewise-constant voltages, FFT of the current samples; THD up to ``f_max = thd_max_carriers * f_sw``,
   mean over the phases.

Figures of merit (per variant): the modulator's ``linear_limit_v`` (alpha-beta peak), the fundamental
phase voltage and current, the voltage and current THD. Three phases add the line-to-line voltages, the
modulation index and the DC-bus utilisation against sinusoidal PWM. Six and five phases add the second VSD
plane ([`SecondPlane`][pmsmjax.jobs.pwm_comparison.SecondPlane]): its period-average voltage (RMS and peak
over the window's periods: zero for the methods that null it), its current, and the harmonic phase currents of
the orders that live in it (six phases the 5th and 7th, keys ``z_*``; five phases the 3rd and 7th, keys
``xy_*``).

Variants: ``<modulator>`` (averaged bridge), ``<modulator>_switching`` (switching bridge, no dead time)
and ``<modulator>_switching_deadtime`` (dead time ``dead_time_s``), for the modulators of
[`PHASE_COUNTS`][pmsmjax.jobs.pwm_comparison.PHASE_COUNTS] (three phases: ``sinusoidal``,
``third_harmonic``, ``min_max``, ``svpwm``; six: [`SIX_PHASE_PWMS`][pmsmjax.presets.six_phase.SIX_PHASE_PWMS];
five: [`FIVE_PHASE_PWMS`][pmsmjax.presets.five_phase.FIVE_PHASE_PWMS]).
"""

import dataclasses
from collections.abc import Callable, Mapping

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from pmsmjax._types import Array
from pmsmjax.analysis.spectra import piecewise_constant_spectrum, sampled_spectrum, thd
from pmsmjax.analysis.within_period import dense_window
from pmsmjax.assemble import with_parts
from pmsmjax.drive import Drive
from pmsmjax.frames.multiphase import FIVE_PHASE, SIX_PHASE, PhaseLayout, inverse_vsd, vsd
from pmsmjax.frames.three_phase import alpha_beta_to_abc
from pmsmjax.inverters import (
    SVPWM,
    AbstractBridge,
    AbstractModulator,
    AveragedBridge,
    MinMaxPWM,
    MultiPhaseAveragedBridge,
    MultiPhaseSwitchingBridge,
    SinusoidalPWM,
    SwitchingBridge,
    ThirdHarmonicPWM,
)
from pmsmjax.presets.five_phase import FIVE_PHASE_PWMS, five_phase_drive
from pmsmjax.presets.six_phase import SIX_PHASE_PWMS, six_phase_drive
from pmsmjax.presets.three_phase import book_drive, book_scenario
from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.simulate import period_inputs, simulate
from pmsmjax.spec.validation import ParameterError
from pmsmjax.units import rpm_to_rad_s

__all__ = [
    "BRIDGES",
    "MODULATORS",
    "PHASE_COUNTS",
    "CompareSettings",
    "PhaseCount",
    "SecondPlane",
    "analyse",
    "compare",
    "run_variant",
    "steady_state",
]

BRIDGES = ("averaged", "switching", "deadtime")
#: The three-phase modulators (the book, ch. 2), name -> constructor.
MODULATORS = {
    "sinusoidal": SinusoidalPWM,
    "third_harmonic": ThirdHarmonicPWM,
    "min_max": MinMaxPWM,
    "svpwm": SVPWM,
}
THD_DEFINITION = (
    "sqrt(sum of squared peak amplitudes of every Fourier component of the window but DC and the "
    "fundamental, up to thd_max_frequency_hz) / fundamental"
)


@dataclasses.dataclass(frozen=True)
class SecondPlane:
    """The VSD plane of a multi-phase winding besides alpha-beta (the book, ch. 8 and 10).

    `key`: its name in the figures' keys (``z``, ``xy``); `name`: in text (``z1-z2``, ``x-y``); `orders`:
    the two harmonic orders of the phase currents that live in it (six phases 5 and 7, five phases 3 and 7).
    """

    key: str
    name: str
    orders: tuple[int, int]


@dataclasses.dataclass(frozen=True)
class PhaseCount:
    """What the comparison takes from the phase count; the procedure is the same for all.

    - `modulators`: the variants, name -> constructor; `default_bridges`: the bridge variants run unless
      the settings name others.
    - `base_drive`: builds the drive that reaches the operating point (module docstring, step 1).
    - The frames: `averaged_bridge(u_dc)` and `switching_bridge(u_dc, dead_time or None)` build the
      bridges; `to_phases` maps the dense window's ``(K, m)`` stationary voltages, V, to ``(K, n)`` phase
      voltages; the waveforms name the phase currents and voltages `current_key` and `voltage_key`.
    - `second_plane`: that of a multi-phase winding (its figures of merit), with the winding's `layout`;
      None for three phases, which report the line-to-line voltages, the modulation index and the DC-bus
      utilisation against sinusoidal PWM instead (the book, ch. 2).
    - `record`: what the report's settings add (the multi-phase drives' control scheme); `thd_definition`.
    """

    n: int
    modulators: Mapping[str, Callable[[], AbstractModulator]]
    default_bridges: tuple[str, ...]
    base_drive: Callable[[], Drive]
    averaged_bridge: Callable[[float], AbstractBridge]
    switching_bridge: Callable[[float, float | None], AbstractBridge]
    to_phases: Callable[[Array], Array]
    current_key: str
    voltage_key: str
    thd_definition: str
    second_plane: SecondPlane | None = None
    layout: PhaseLayout | None = None
    record: Mapping[str, object] = dataclasses.field(default_factory=dict)


def _multi_phase(layout: PhaseLayout, modulators, base_drive, plane: SecondPlane) -> PhaseCount:
    """The comparison on an n-phase winding: n-leg bridges, VSD frames, one second plane."""
    return PhaseCount(
        n=layout.n,
        modulators=modulators,
        default_bridges=("averaged", "switching"),
        base_drive=base_drive,
        averaged_bridge=lambda u_dc: MultiPhaseAveragedBridge(u_dc, layout),
        switching_bridge=lambda u_dc, dead_time: MultiPhaseSwitchingBridge(
            u_dc, dead_time=dead_time, layout=layout
        ),
        to_phases=lambda u_vsd: inverse_vsd(u_vsd, layout),
        current_key="i_phase",
        voltage_key="u_phase",
        thd_definition=THD_DEFINITION + ", mean over the phases",
        second_plane=plane,
        layout=layout,
        record={
            "phases": layout.n,
            "control": f"conventional (dq loops only, {plane.name} voltage reference 0)",
        },
    )


#: The phase counts compared: 3, 6 and 5 -> [`PhaseCount`][pmsmjax.jobs.pwm_comparison.PhaseCount].
PHASE_COUNTS = {
    3: PhaseCount(
        n=3,
        modulators=MODULATORS,
        default_bridges=BRIDGES,
        base_drive=book_drive,
        averaged_bridge=AveragedBridge,
        switching_bridge=lambda u_dc, dead_time: SwitchingBridge(u_dc, dead_time=dead_time),
        to_phases=alpha_beta_to_abc,
        current_key="i_abc",
        voltage_key="u_abc",
        thd_definition=THD_DEFINITION,
    ),
    6: _multi_phase(
        SIX_PHASE,
        SIX_PHASE_PWMS,
        lambda: six_phase_drive(control="conventional", pwm="four-vector"),
        SecondPlane("z", "z1-z2", (5, 7)),
    ),
    5: _multi_phase(
        FIVE_PHASE,
        FIVE_PHASE_PWMS,
        lambda: five_phase_drive(control="conventional", pwm="near-four-vector"),
        SecondPlane("xy", "x-y", (3, 7)),
    ),
}


@dataclasses.dataclass(frozen=True)
class CompareSettings:
    """Operating point and analysis sizes.

    - `speed_rpm`, `load_nm`: steady operating point (reached through the book scenario).
    - `dead_time_s`: dead time of the ``_deadtime`` variants, s.
    - `settle_cycles`, `window_cycles`: fundamental periods settled, then analysed.
    - `samples_per_period`: current samples per PWM period.
    - `thd_max_carriers`: THD includes components up to this many times the switching frequency.
    - `modulators`: which modulators (None: all of the phase count); `bridges`: subset of
      ``("averaged", "switching", "deadtime")`` (None: all three for three phases, the first two for more).
    - `phases`: 3 (default), 6 or 5.
    """

    speed_rpm: float = 1000.0
    load_nm: float = 10.0
    dead_time_s: float = 2e-6
    settle_cycles: int = 2
    window_cycles: int = 2
    samples_per_period: int = 32
    thd_max_carriers: float = 4.0
    modulators: tuple[str, ...] | None = None
    bridges: tuple[str, ...] | None = None
    phases: int = 3

    @property
    def phase_count(self) -> PhaseCount:
        """The [`PhaseCount`][pmsmjax.jobs.pwm_comparison.PhaseCount] of `phases` (raises for another)."""
        if self.phases not in PHASE_COUNTS:
            raise ParameterError(
                f"phases must be one of {', '.join(map(str, PHASE_COUNTS))}, got {self.phases!r}."
            )
        return PHASE_COUNTS[self.phases]

    @property
    def modulator_names(self) -> tuple[str, ...]:
        """The modulators compared (all of the phase count when `modulators` is None)."""
        table = self.phase_count.modulators
        return tuple(table) if self.modulators is None else tuple(self.modulators)

    @property
    def bridge_names(self) -> tuple[str, ...]:
        """The bridge variants run (the phase count's default when `bridges` is None)."""
        return self.phase_count.default_bridges if self.bridges is None else tuple(self.bridges)

    def check(self, Ts: float, pole_pairs: int) -> int:
        """Validate; return the PWM periods per fundamental period (must be whole)."""
        table = self.phase_count.modulators
        unknown = [m for m in self.modulator_names if m not in table]
        if unknown:
            raise ParameterError(
                f"unknown {self.phases}-phase modulators {unknown}: choose from {list(table)}."
            )
        bad = [b for b in self.bridge_names if b not in BRIDGES]
        if bad:
            raise ParameterError(f"unknown bridges {bad}: choose from {', '.join(BRIDGES)}.")
        if self.speed_rpm <= 0:
            raise ParameterError(f"speed_rpm must be > 0 for a spectrum, got {self.speed_rpm}.")
        for name in ("settle_cycles", "window_cycles"):
            v = getattr(self, name)
            if not isinstance(v, int) or v < (0 if name == "settle_cycles" else 1):
                raise ParameterError(f"{name} must be a whole number of fundamental periods, got {v!r}.")
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
    """Drive state at the end of the book scenario to the operating point (the drive as given)."""
    scenario = book_scenario(settings.speed_rpm, settings.load_nm)
    xs = period_inputs(scenario, drive.Ts)
    run = eqx.filter_jit(lambda d, s, x: jax.lax.scan(lambda c, xi: (d.step(c, xi)[0], None), s, x)[0])
    return run(drive, drive.init(), xs)


def run_variant(drive: Drive, start, settings: CompareSettings, per_cycle: int) -> dict:
    """Simulate one variant from ``start`` and return its window's waveforms (NumPy).

    Returns ``t_i (N,)`` s and the phase currents ``(N, n)`` A (uniform samples; key ``i_abc`` for three
    phases, ``i_phase`` for more), ``t_u (K+1,)`` s and the piecewise-constant phase voltages ``(K, n)`` V
    (``u_abc``, ``u_phase``), ``omega_m`` (mean over the window, rad/s). Multi-phase windings add
    ``i_vsd (N, 4)`` A, ``u_vsd (K, 4)`` V and ``u_vsd_period (P, 4)`` V (each period's average of the
    applied voltage, dead-time errors included).
    """
    pc = settings.phase_count
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
    dense, t_u, u_stationary = dense_window(drive, window, M)
    i_phase = np.asarray(jax.vmap(jax.vmap(machine.phase_currents))(dense)).reshape(-1, pc.n)
    u_phase = np.asarray(pc.to_phases(jnp.asarray(u_stationary)))
    wave = {"t_i": (np.arange(n_window * M) + 1) * Ts / M, pc.current_key: i_phase}
    if pc.second_plane is None:
        wave |= {"t_u": t_u, pc.voltage_key: u_phase}
    else:
        # Each period's average: the integral of the piecewise-constant voltage between period starts,
        # which are cut points of t_u.
        integral = np.concatenate(
            [np.zeros((1, u_stationary.shape[-1])), np.cumsum(np.diff(t_u)[:, None] * u_stationary, 0)]
        )
        starts = np.searchsorted(t_u, np.arange(n_window + 1) * Ts - 1e-3 * Ts)
        wave |= {
            "i_vsd": np.asarray(vsd(jnp.asarray(i_phase), pc.layout))[:, :4],
            "t_u": t_u,
            "u_vsd": np.asarray(u_stationary),
            pc.voltage_key: u_phase,
            "u_vsd_period": np.diff(integral[starts], axis=0) / Ts,
        }
    wave["omega_m"] = float(np.mean(np.asarray(window.omega_m)))
    return wave


def analyse(wave: dict, settings: CompareSettings, Ts: float, u_dc: float) -> dict:
    """Spectra and figures of merit of one variant's window (module docstring); the spectra under
    ``"spectra"``: ``phase_voltage``, ``current`` and for three phases ``line_voltage``."""
    pc, plane = settings.phase_count, settings.phase_count.second_plane
    cycles = settings.window_cycles
    window_s = wave["t_u"][-1]
    f_max = settings.thd_max_carriers / Ts
    n_max = int(round(f_max * window_s))
    u = wave[pc.voltage_key]
    spectra = {"phase_voltage": piecewise_constant_spectrum(wave["t_u"], u, cycles, n_max)}
    if plane is None:
        u_lines = np.stack([u[:, 0] - u[:, 1], u[:, 1] - u[:, 2], u[:, 2] - u[:, 0]], 1)
        spectra["line_voltage"] = piecewise_constant_spectrum(wave["t_u"], u_lines, cycles, n_max)
    spectra["current"] = sampled_spectrum(wave[pc.current_key], window_s, cycles, n_max)
    mean = lambda x: float(np.mean(x))
    units = {"phase_voltage": "v", "line_voltage": "v", "current": "a"}
    out = {f"fundamental_{k}_{units[k]}": mean(s.fundamental) for k, s in spectra.items()}
    if plane is not None:
        z_avg = np.hypot(wave["u_vsd_period"][:, 2], wave["u_vsd_period"][:, 3])
        i_z = np.hypot(wave["i_vsd"][:, 2], wave["i_vsd"][:, 3])
        out[f"{plane.key}_average_voltage_rms_v"] = float(np.sqrt(np.mean(z_avg**2)))
        out[f"{plane.key}_average_voltage_peak_v"] = float(np.max(z_avg))
        out[f"{plane.key}_current_rms_a"] = float(np.sqrt(np.mean(i_z**2)))
    thd_names = {"phase_voltage": "voltage", "line_voltage": "line_voltage", "current": "current"}
    out |= {f"{thd_names[k]}_thd_pct": 100.0 * mean(thd(s, f_max)) for k, s in spectra.items()}
    if plane is None:
        out["modulation_index"] = out["fundamental_phase_voltage_v"] / (0.5 * u_dc)
    else:
        spec_z = sampled_spectrum(wave["i_vsd"][:, 2:4], window_s, cycles, n_max)
        for k in plane.orders:
            out[f"harmonic_{k}_current_a"] = mean(spectra["current"].amplitudes[k * cycles])
        for k in plane.orders:
            out[f"harmonic_{k}_{plane.key}_current_a"] = mean(spec_z.amplitudes[k * cycles])
    out["spectra"] = spectra
    return out


def sinusoidal(u_dc: float) -> float:
    """Sinusoidal PWM's linear limit, V peak: the reference of the DC-bus utilisation (the book, ch. 2)."""
    return float(SinusoidalPWM().linear_limit(u_dc))


def _progress_line(name: str, e: dict, plane: SecondPlane | None) -> str:
    line = (
        f"{name:32s} U1 {e['fundamental_phase_voltage_v']:7.2f} V  THD u {e['voltage_thd_pct']:6.2f} %  "
        f"THD i {e['current_thd_pct']:6.3f} %"
    )
    if plane is not None:
        h1, h2 = plane.orders
        line += (
            f"  u_{plane.key} avg {e[f'{plane.key}_average_voltage_rms_v']:6.2f} V  "
            f"i{h1} {e[f'harmonic_{h1}_current_a']:.3f} A  i{h2} {e[f'harmonic_{h2}_current_a']:.3f} A"
        )
    return line


def compare(settings: CompareSettings = CompareSettings(), base: Drive | None = None, progress=None) -> dict:
    """Run every variant; return a dict with ``settings`` (the report's record), ``entries`` (name ->
    figures), ``waves`` and ``spectra`` (name -> the
    [`run_variant`][pmsmjax.jobs.pwm_comparison.run_variant] waveforms and the
    [`pmsmjax.analysis.spectra.Spectrum`][pmsmjax.analysis.spectra.Spectrum] s).

    `base`: the drive to compare on (default: the phase count's
    [`PhaseCount.base_drive`][pmsmjax.jobs.pwm_comparison.PhaseCount]), with `settings.phases` phases;
    `progress`: optional callable taking a line.
    """
    pc = settings.phase_count
    base = pc.base_drive() if base is None else base
    per_cycle = settings.check(base.Ts, base.machine.motor.pole_pairs)
    if base.machine.n_phases != settings.phases:
        raise ParameterError(
            f"the base drive has {base.machine.n_phases} phases, the settings {settings.phases}."
        )
    u_dc = float(base.bridge.u_dc)
    start = steady_state(base, settings)
    reached = float(np.asarray(start.machine.omega_m)) / rpm_to_rad_s(1.0)
    if abs(reached - settings.speed_rpm) > 0.02 * abs(settings.speed_rpm):
        # A drive that did not reach the point runs saturated: its spectra would compare nothing.
        raise ParameterError(
            f"the drive reached {reached:.0f} r/min, not the {settings.speed_rpm:g} r/min asked for, at "
            f"{settings.load_nm:g} N m (voltage or current limit): pick an operating point inside its limits."
        )
    bridges = {
        "averaged": ("", pc.averaged_bridge(u_dc)),
        "switching": ("_switching", pc.switching_bridge(u_dc, None)),
        "deadtime": ("_switching_deadtime", pc.switching_bridge(u_dc, settings.dead_time_s)),
    }
    entries, waves, spectra = {}, {}, {}
    for mod_name in settings.modulator_names:
        modulator = pc.modulators[mod_name]()
        for bridge_key in settings.bridge_names:
            suffix, bridge = bridges[bridge_key]
            name = mod_name + suffix
            drive = with_parts(base, {"modulator": modulator, "bridge": bridge})
            wave = run_variant(drive, start, settings, per_cycle)
            figures = analyse(wave, settings, base.Ts, u_dc)
            spectra[name] = figures.pop("spectra")
            limit = float(modulator.linear_limit(u_dc))
            entries[name] = {
                "modulator": mod_name,
                "bridge": "averaged" if bridge_key == "averaged" else "switching",
                "dead_time_s": settings.dead_time_s if bridge_key == "deadtime" else 0.0,
                "linear_limit_v": limit,
                **({} if pc.second_plane else {"dc_bus_utilisation_vs_sinusoidal": limit / sinusoidal(u_dc)}),
                **figures,
                "speed_rpm": wave.pop("omega_m") * 60.0 / (2.0 * np.pi),
            }
            waves[name] = wave
            if progress:
                progress(_progress_line(name, entries[name], pc.second_plane))
    fields = dataclasses.asdict(settings)
    record = {k: v for k, v in fields.items() if k not in ("modulators", "bridges", "phases")}
    return {
        "settings": {
            **record,
            "modulators": list(settings.modulator_names),
            "bridges": list(settings.bridge_names),
            **pc.record,
            "u_dc_v": u_dc,
            "Ts_s": base.Ts,
            "thd_max_frequency_hz": settings.thd_max_carriers / base.Ts,
            "thd_definition": pc.thd_definition,
        },
        "entries": entries,
        "waves": waves,
        "spectra": spectra,
    }
