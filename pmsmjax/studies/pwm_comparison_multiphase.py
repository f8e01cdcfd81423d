"""The six-phase PWM comparison (BOOK.md chapter 8): every dual three-phase modulator at one steady operating
point, with the averaged and the switching-resolved six-leg bridge.

Procedure (as :mod:`pmsmjax.studies.pwm_comparison` for three phases):

1. The six-phase drive with **conventional** control (dq current loops only: the z1-z2 voltage reference is
   zero and nothing corrects z1-z2 currents, so each modulator's own z1-z2 voltage shows in the currents;
   a z1-z2 loop would fight the two-vector method, which cannot apply z1-z2 voltage) and four-vector
   SVPWM on the averaged bridge runs the book scenario to the operating point.
2. Each variant (modulator x bridge) continues from there at the final references for ``settle_cycles``
   fundamental periods, then ``window_cycles`` are analysed.
3. Inside every analysed period the phase currents are sampled ``samples_per_period`` times
   (:func:`pmsmjax.analysis.within_period.dense_window`) and the phase voltages rebuilt exactly from the
   bridge's constant-voltage intervals.
4. Figures of merit: the modulator's ``linear_limit_v`` (alpha-beta peak), the fundamental phase voltage
   and current, the z1-z2 period-average voltage (RMS and peak over the window's periods: zero for
   four-vector, decoupled and double zero-sequence PWM, not for two-vector), the current THD up to
   ``thd_max_carriers`` times the switching frequency, and the 5th and 7th harmonic phase currents (the
   harmonics of orders ``6k -+ 1``, k odd, that live in z1-z2), all averaged over the six phases.

**Five phases** (``SixPhaseCompareSettings(phases=5)``, ``pmsmjax pwm-compare --phases 5``, BOOK.md chapter
10): the same procedure on the five-phase drive (:func:`pmsmjax.presets.five_phase.five_phase_drive`,
conventional control) with its modulators (:data:`~pmsmjax.presets.five_phase.FIVE_PHASE_PWMS`) and the
five-leg bridges; the second plane is x-y and the harmonics reported are the 3rd and 7th (orders
``5k +- 2``, the ones that live in x-y): keys ``x_y_average_voltage_*``, ``harmonic_3_current_a``,
``harmonic_3_xy_current_a``, ...

Variants: ``<modulator>`` (averaged bridge), ``<modulator>_switching`` (:class:`MultiPhaseSwitchingBridge`,
no dead time) and optionally ``<modulator>_switching_deadtime``; modulators ``four-vector``,
``two-vector``, ``decoupled``, ``double-zs``.
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
from pmsmjax.frames.multiphase import inverse_vsd, vsd
from pmsmjax.inverters.multiphase_bridges import MultiPhaseAveragedBridge, MultiPhaseSwitchingBridge
from pmsmjax.presets.six_phase import SIX_PHASE_PWMS, six_phase_drive
from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.simulate import simulate
from pmsmjax.studies.pwm_comparison import steady_state
from pmsmjax.units import rpm_to_rad_s

__all__ = ["SixPhaseCompareSettings", "compare_six_phase", "run_variant", "analyse"]

BRIDGES = ("averaged", "switching", "deadtime")


@dataclasses.dataclass(frozen=True)
class SixPhaseCompareSettings:
    """Operating point and analysis sizes (see :class:`pmsmjax.studies.pwm_comparison.CompareSettings`).

    `bridges`: subset of ``("averaged", "switching", "deadtime")``; `dead_time_s` for the last. `phases`:
    6 (default) or 5; with 5, `modulators` defaults to the five-phase ones.
    """

    speed_rpm: float = 1000.0
    load_nm: float = 10.0
    dead_time_s: float = 2e-6
    settle_cycles: int = 2
    window_cycles: int = 2
    samples_per_period: int = 32
    thd_max_carriers: float = 4.0
    modulators: tuple[str, ...] | None = None
    bridges: tuple[str, ...] = ("averaged", "switching")
    phases: int = 6

    @property
    def table(self) -> dict:
        """The modulators of the phase count (name -> constructor)."""
        if self.phases == 5:
            from pmsmjax.presets.five_phase import FIVE_PHASE_PWMS

            return FIVE_PHASE_PWMS
        return SIX_PHASE_PWMS

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.table) if self.modulators is None else tuple(self.modulators)

    @property
    def plane(self) -> str:
        """The second VSD plane's name: z (six phases) or xy (five)."""
        return "xy" if self.phases == 5 else "z"

    @property
    def orders(self) -> tuple[int, int]:
        """The harmonic orders that live in the second plane, reported: 5, 7 (six phases) or 3, 7 (five)."""
        return (3, 7) if self.phases == 5 else (5, 7)

    def check(self, Ts: float, pole_pairs: int) -> int:
        """Validate; return the PWM periods per fundamental period (must be whole)."""
        if self.phases not in (5, 6):
            raise ParameterError(f"phases must be 5 or 6, got {self.phases!r}.")
        word = "five" if self.phases == 5 else "six"
        unknown = [m for m in self.names if m not in self.table]
        if unknown:
            raise ParameterError(
                f"unknown {word}-phase modulators {unknown}: choose from {list(self.table)}."
            )
        bad = [b for b in self.bridges if b not in BRIDGES]
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
        need = int(np.floor(2 * self.thd_max_carriers)) + 2
        if not isinstance(self.samples_per_period, int) or self.samples_per_period < need:
            raise ParameterError(
                f"samples_per_period must be an int >= {need}, got {self.samples_per_period}."
            )
        return int(round(per_cycle))


def run_variant(drive: Drive, start, settings: SixPhaseCompareSettings, per_cycle: int) -> dict:
    """Simulate one variant from ``start``; the window's waveforms (NumPy): ``t_i (N,)`` s, ``i_phase
    (N, n)`` A and ``i_vsd (N, 4)`` A (uniform samples), ``t_u (K+1,)`` s, ``u_vsd (K, 4)`` and ``u_phase
    (K, 6)`` V (piecewise constant), ``u_vsd_period (P, 4)`` V (each period's average of the applied
    voltage), ``omega_m``."""
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
    layout = machine.layout
    dense, t_u, u_vsd = dense_window(drive, window, M)
    i_phase = jax.vmap(jax.vmap(lambda s: machine.phase_currents(s)))(dense)
    i_phase = np.asarray(i_phase).reshape(-1, layout.n)
    # Each period's average of the voltage the bridge applied (dead-time errors included): the integral of
    # the piecewise-constant voltage between period starts, which are cut points of t_u.
    integral = np.concatenate([np.zeros((1, u_vsd.shape[-1])), np.cumsum(np.diff(t_u)[:, None] * u_vsd, 0)])
    starts = np.searchsorted(t_u, np.arange(n_window + 1) * Ts - 1e-3 * Ts)
    u_period = np.diff(integral[starts], axis=0) / Ts
    return {
        "t_i": (np.arange(n_window * M) + 1) * Ts / M,
        "i_phase": i_phase,
        "i_vsd": np.asarray(vsd(jnp.asarray(i_phase), layout))[:, :4],
        "t_u": t_u,
        "u_vsd": np.asarray(u_vsd),
        "u_phase": np.asarray(inverse_vsd(jnp.asarray(u_vsd), layout)),
        "u_vsd_period": u_period,
        "omega_m": float(np.mean(np.asarray(window.omega_m))),
    }


def analyse(wave: dict, settings: SixPhaseCompareSettings, Ts: float) -> dict:
    """Spectra and figures of merit of one variant's window."""
    cycles = settings.window_cycles
    window_s = wave["t_u"][-1]
    f_max = settings.thd_max_carriers / Ts
    n_max = int(round(f_max * window_s))
    spec_u = piecewise_constant_spectrum(wave["t_u"], wave["u_phase"], cycles, n_max)
    spec_i = sampled_spectrum(wave["i_phase"], window_s, cycles, n_max)
    spec_z = sampled_spectrum(wave["i_vsd"][:, 2:4], window_s, cycles, n_max)
    mean = lambda x: float(np.mean(x))
    z_avg = np.hypot(wave["u_vsd_period"][:, 2], wave["u_vsd_period"][:, 3])
    i_z = np.hypot(wave["i_vsd"][:, 2], wave["i_vsd"][:, 3])
    z = settings.plane
    out = {
        "fundamental_phase_voltage_v": mean(spec_u.fundamental),
        "fundamental_current_a": mean(spec_i.fundamental),
        f"{z}_average_voltage_rms_v": float(np.sqrt(np.mean(z_avg**2))),
        f"{z}_average_voltage_peak_v": float(np.max(z_avg)),
        f"{z}_current_rms_a": float(np.sqrt(np.mean(i_z**2))),
        "voltage_thd_pct": 100.0 * mean(thd(spec_u, f_max)),
        "current_thd_pct": 100.0 * mean(thd(spec_i, f_max)),
    }
    for k in settings.orders:
        out[f"harmonic_{k}_current_a"] = mean(spec_i.amplitudes[k * cycles])
    for k in settings.orders:
        out[f"harmonic_{k}_{z}_current_a"] = mean(spec_z.amplitudes[k * cycles])
    out["spectra"] = {"phase_voltage": spec_u, "current": spec_i}
    return out


def compare_six_phase(
    settings: SixPhaseCompareSettings = SixPhaseCompareSettings(), base: Drive | None = None, progress=None
) -> dict:
    """Run every variant; ``{"settings", "entries", "waves", "spectra"}`` as
    :func:`pmsmjax.studies.pwm_comparison.compare`. `base`: the drive (default: six-phase, conventional
    control,
    four-vector SVPWM, averaged bridge)."""
    if base is None and settings.phases == 5:
        from pmsmjax.presets.five_phase import five_phase_drive

        base = five_phase_drive(control="conventional", pwm="near-four-vector")
    base = six_phase_drive(control="conventional", pwm="four-vector") if base is None else base
    per_cycle = settings.check(base.Ts, base.machine.motor.pole_pairs)
    layout = base.machine.layout
    if layout.n != settings.phases:
        raise ParameterError(f"the base drive has {layout.n} phases, the settings {settings.phases}.")
    u_dc = float(base.bridge.u_dc)
    start = steady_state(base, settings)  # the book scenario to (speed_rpm, load_nm)
    bridges = {
        "averaged": ("", MultiPhaseAveragedBridge(u_dc, layout)),
        "switching": ("_switching", MultiPhaseSwitchingBridge(u_dc, layout=layout)),
        "deadtime": (
            "_switching_deadtime",
            MultiPhaseSwitchingBridge(u_dc, dead_time=settings.dead_time_s, layout=layout),
        ),
    }
    z, (h1, h2) = settings.plane, settings.orders
    entries, waves, spectra = {}, {}, {}
    for mod_name in settings.names:
        modulator = settings.table[mod_name]()
        for bridge_key in settings.bridges:
            suffix, bridge = bridges[bridge_key]
            name = mod_name + suffix
            drive = eqx.tree_at(lambda d: (d.modulator, d.bridge), base, (modulator, bridge))
            wave = run_variant(drive, start, settings, per_cycle)
            figures = analyse(wave, settings, base.Ts)
            spectra[name] = figures.pop("spectra")
            entries[name] = {
                "modulator": mod_name,
                "bridge": "averaged" if bridge_key == "averaged" else "switching",
                "dead_time_s": settings.dead_time_s if bridge_key == "deadtime" else 0.0,
                "linear_limit_v": float(modulator.linear_limit(u_dc)),
                **figures,
                "speed_rpm": wave.pop("omega_m") * 60.0 / (2.0 * np.pi),
            }
            waves[name] = wave
            if progress:
                e = entries[name]
                progress(
                    f"{name:30s} U1 {e['fundamental_phase_voltage_v']:6.2f} V  u_{z} avg "
                    f"{e[f'{z}_average_voltage_rms_v']:6.2f} V  THD i {e['current_thd_pct']:6.2f} %  "
                    f"i{h1} {e[f'harmonic_{h1}_current_a']:.3f} A  "
                    f"i{h2} {e[f'harmonic_{h2}_current_a']:.3f} A"
                )
    return {
        "settings": {
            **dataclasses.asdict(settings),
            "modulators": list(settings.names),
            "phases": settings.phases,
            "control": "conventional (dq loops only, "
            + ("x-y" if settings.phases == 5 else "z1-z2")
            + " voltage reference 0)",
            "u_dc_v": u_dc,
            "Ts_s": base.Ts,
            "thd_max_frequency_hz": settings.thd_max_carriers / base.Ts,
            "thd_definition": "sqrt(sum of squared peak amplitudes of every Fourier component of the window "
            "but DC and the fundamental, up to thd_max_frequency_hz) / fundamental, mean over the phases",
        },
        "entries": entries,
        "waves": waves,
        "spectra": spectra,
    }
