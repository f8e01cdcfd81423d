"""Where HF injection holds on the saturated-ipm and pm-syrm flux maps: the predicted injection region
(pmsmjax/estimators/injection_region.py) against closed-loop runs, and the hybrid with and without its
hand-over by current. Figures for docs/chapters/06_hfi.md.

1. **Region**: along each map's MTPA locus the saliency signal (over its no-load value), the uncompensated
   lock angle and the compensated loop gain, and the region's end (``docs/assets/ch06_injection_region.png``).
2. **Ramp**: rotor held at standstill (imposed mechanics, 0.4 rad off the estimate), the current references
   ramped along the motoring MTPA locus over 0.9 s, each injection method designed on the map at no load,
   plain and map-compensated; the angle error (modulo pi) against ``i_q*`` and where it first exceeds
   45 degrees.
3. **Hybrid** on saturated-ipm (speed loop 30 rad/s: at the file's 119 rad/s the injection's 299 rad/s PLL
   cannot carry it even at no load), rotor 30 degrees off, standstill while the load ramps 0 -> 5 N m
   (0.1-0.4 s; the region ends at 3.2 N m), then a start to 600 r/min (0.5-0.7 s), and a 5 N m step at
   0.1 s with the same start: angle error with the hand-over by current and by speed alone
   (``docs/assets/ch06_hybrid_handover.png``).

    python -m benchmarks.hfi_region
"""

import math

import numpy as np

from pmsmjax import presets
from pmsmjax.analysis.observer_errors import angle_error, angle_error_modulo_pi
from pmsmjax.assemble import (
    assemble,
    map_injection_design,
    spec_drive,
    spec_flux_map,
    spec_motor,
    with_map_aware_estimator,
    with_parts,
)
from pmsmjax.estimators.hfi_cross_saturation import cross_saturation_compensated, injection_model
from pmsmjax.estimators.hybrid import with_current_handover
from pmsmjax.estimators.injection_region import spec_injection_region
from pmsmjax.io.drive_files import drive_spec
from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.simulate import simulate
from pmsmjax.units import rpm_to_rad_s

MAPS = ("saturated-ipm", "pm-syrm")
METHODS = ("hfi-pulsating", "hfi-rotating")


def region_rows(name: str):
    spec = drive_spec(name)
    compensated = spec_injection_region(spec)
    plain = spec_injection_region(spec, compensated=False)
    print(
        f"{name}: compensated region to {compensated.max_torque_nm:.3g} N m, |i_q| "
        f"{compensated.max_i_q_a:.3g} A ({compensated.limited_by}); uncompensated to "
        f"{plain.max_torque_nm:.3g} N m, |i_q| "
        f"{plain.max_i_q_a:.3g} A ({plain.limited_by}); smallest signal on the locus "
        f"{np.min(compensated.signal):.3f}; loop gain reaches 1 at i_q = "
        f"{_first(compensated.i_q, compensated.loop_gain >= 1.0)} A"
    )
    return compensated, plain


def _first(i_q, mask) -> str:
    motoring = (i_q > 0) & mask
    return f"{i_q[motoring].min():.3g}" if motoring.any() else "none"


def ramp(name: str, method: str, top_a: float, duration: float = 1.0) -> dict:
    spec = drive_spec(name)
    compensated = spec_injection_region(spec)
    i_q = np.linspace(0.0, top_a, 41)
    i_d = np.interp(i_q, compensated.i_q, compensated.i_d)
    times = list(0.05 + (duration - 0.1) * np.linspace(0.0, 1.0, 41))
    motor = injection_model(spec.flux_map, spec_motor(spec), (0.0, 0.0))
    drive = presets.with_observer(
        spec_drive(spec, mode="current", mechanics="imposed"), method, motor, None, startup=False
    )
    drives = {
        "plain": drive,
        "compensated": with_parts(
            drive, {"estimator": cross_saturation_compensated(drive.estimator, spec_flux_map(spec))}
        ),
    }
    sc = Scenario(
        duration,
        id_ref=Profile.piecewise([0.0, *times], [0.0, *i_d], "linear"),
        iq_ref=Profile.piecewise([0.0, *times], [0.0, *i_q], "linear"),
    )
    out = {}
    for label, d in drives.items():
        tr = simulate(d, sc, initial_state=d.init(theta_e=0.4))
        t = np.asarray(tr.t)
        e = np.degrees(np.asarray(angle_error_modulo_pi(tr.theta_e_est, tr.theta_e)))
        reference = np.interp(t, [0.0, *times], [0.0, *i_q])
        lost = np.abs(e) > 45.0
        lost_at = float(reference[np.argmax(lost)]) if lost.any() else math.nan
        small = np.abs(e) < 1.0
        held = float(reference[np.argmax(~small & (t > 0.05))]) if (~small & (t > 0.05)).any() else top_a
        out[label] = dict(t=t, i_q=reference, error=e, lost_at=lost_at, within_1deg_to=held)
        print(
            f"  {name} {method} {label:11s}: error within 1 deg up to i_q* = {held:.2f} A, beyond 45 deg "
            f"from {lost_at:.2f} A"
        )
    return out


def hybrid_runs(load_nm: float = 5.0, speed_bandwidth: float = 30.0) -> dict:
    spec = drive_spec("saturated-ipm")
    region = spec_injection_region(spec)
    foc = assemble(spec, "pi", options={"speed_bandwidth": speed_bandwidth})
    model, options = map_injection_design(spec, "hybrid", spec_motor(spec), {"polarity": False})
    drive = with_map_aware_estimator(
        spec, presets.with_observer(foc, "hybrid", model, options, startup=False)
    )
    variants = {
        "by speed alone": drive,
        "by speed and current": with_parts(
            drive, {"estimator": with_current_handover(drive.estimator, region.max_current_a)}
        ),
    }
    w = rpm_to_rad_s(600.0)
    speed = Profile.piecewise([0.0, 0.5, 0.7, 0.9], [0.0, 0.0, w, w], "linear")
    scenarios = {
        "load ramp": Scenario(
            0.9, speed, Profile.piecewise([0.0, 0.1, 0.4, 0.9], [0, 0, load_nm, load_nm], "linear")
        ),
        "load step": Scenario(0.9, speed, Profile.step(0.1, 0.0, load_nm)),
    }
    out = {}
    for sc_name, sc in scenarios.items():
        for label, d in variants.items():
            tr = simulate(d, sc, initial_state=d.init(theta_e=math.radians(30.0)))
            t = np.asarray(tr.t)
            e = np.degrees(np.asarray(angle_error(tr.theta_e_est, tr.theta_e)))
            after = t > 0.05
            rms, peak = float(np.sqrt(np.mean(e[after] ** 2))), float(np.max(np.abs(e[after])))
            out[(sc_name, label)] = dict(t=t, error=e, rms=rms, peak=peak)
            print(f"  hybrid, {sc_name}, hand-over {label}: angle error RMS {rms:.2f}, max {peak:.1f} deg")
    return out


def region_figure(regions: dict, path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(11, 6.5), sharex="col")
    for col, (name, (comp, plain)) in enumerate(regions.items()):
        motoring = comp.i_q >= 0
        i_q = comp.i_q[motoring]
        top, bottom = axes[0, col], axes[1, col]
        top.plot(i_q, comp.signal[motoring], label="saliency signal / no-load value")
        top.plot(i_q, np.clip(comp.loop_gain[motoring], -1, 3), label="compensated loop gain F'(0)")
        top.axhline(comp.fraction, color="grey", ls=":", label=f"signal fraction {comp.fraction:g}")
        top.axhline(1.0, color="grey", ls="--", lw=0.8, label="loop gain 1")
        top.axvline(
            comp.max_i_q_a, color="C2", label=f"region end, compensated ({comp.max_torque_nm:.3g} N m)"
        )
        top.axvline(
            plain.max_i_q_a, color="C3", ls="-.", label=f"region end, plain ({plain.max_torque_nm:.3g} N m)"
        )
        top.set_ylabel("signal, gain (1)")
        top.set_title(f"{name}: along the motoring MTPA locus")
        top.legend(fontsize=7)
        bottom.plot(i_q, np.degrees(comp.lock_angle[motoring]), label="uncompensated lock angle")
        bottom.set_ylabel("lock angle th^ - th (el. deg)")
        bottom.set_xlabel("i_q on the MTPA locus (A)")
        twin = bottom.twinx()
        twin.plot(i_q, comp.torque[motoring], color="C1", lw=0.8)
        twin.set_ylabel("torque (N m)", color="C1")
        bottom.legend(fontsize=7, loc="lower left")
        for ax in (top, bottom):
            ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def hybrid_figure(runs: dict, path: str) -> None:
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 3.8), sharey=True)
    for ax, scenario in zip(axes, ("load ramp", "load step"), strict=True):
        for label in ("by speed alone", "by speed and current"):
            r = runs[(scenario, label)]
            ax.plot(r["t"], r["error"], label=f"hand-over {label} (RMS {r['rms']:.1f} deg)")
        ax.set_title(f"saturated-ipm hybrid, 5 N m {scenario} at standstill, start at 0.5 s")
        ax.set_xlabel("time (s)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    axes[0].set_ylabel("angle error th^ - th (el. deg)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main() -> None:
    regions = {name: region_rows(name) for name in MAPS}
    for name, top in (("saturated-ipm", 9.0), ("pm-syrm", 19.0)):
        for method in METHODS:
            ramp(name, method, top)
    region_figure(regions, "docs/assets/ch06_injection_region.png")
    hybrid_figure(hybrid_runs(), "docs/assets/ch06_hybrid_handover.png")


if __name__ == "__main__":
    main()
