"""Where a sensorless observer holds the angle on a measured flux map: a speed x load grid on the two
map drives (saturated-ipm, pm-syrm), for the flux observer on the map
([`pmsmjax.estimators.map_flux_observer`][pmsmjax.estimators.map_flux_observer], ``flux-observer``) and the
best chapter 5 observer on the map drives (``smo-pll`` with the map's angle correction,
[`pmsmjax.estimators.map_angle_corrected`][pmsmjax.estimators.map_angle_corrected]), in float64.

Each grid point: the speed imposed (a dynamometer), current control at the operating current of the load
torque (the least current on the map whose torque is the load and whose steady voltage ``|R i + w J psi(i)|``
stays within 0.9 of ``u_dc / sqrt 3``: MTPA, or field weakening above base speed; "unreachable" where none
within the current limit), held in the observer's frame; the observer starts cold (angle and speed zero)
with the rotor 0.3 rad ahead. Scored over the last 50 ms of 0.25 s: "holds" when the angle error stays
within 3 electrical degrees.

Why it fails, where it can be said: for the flux observer the linearised estimation-error dynamics of
Hinkkanen et al. (2018): flux error ``s^2 + 2 sigma s + w^2`` with ``sigma = sigma0 + zeta |w|`` (its slowest
pole ``-sigma + sqrt(sigma^2 - w^2)`` goes to 0 at standstill: the angle is not observable there) and the
angle loop's double pole at ``-alpha``; the rate of the slowest is written into the JSON. For the
back-EMF observer the back-EMF floor of its angle extraction (``emf_floor_fraction`` of the rated EMF)
and the residual of the map's steady angle correction.

    python -m benchmarks.map_observer_range [--json out.json] [--figure out.png] [--quick]
    python -m benchmarks.map_observer_range --startup [--figure out.png]

``--startup``: the start from standstill of each map drive (its I/f start and hand-over, speed step to
``STARTUP`` with the rated load stepped on) with each observer, on the averaged and the switching bridge:
peak current, largest angle error after the hand-over, steady error under load, and a figure.
"""

import argparse
import json
import math

import jax

jax.config.update("jax_enable_x64", True)

import equinox as eqx  # noqa: E402
import numpy as np  # noqa: E402

from pmsmjax import presets  # noqa: E402
from pmsmjax.analysis.observer_errors import angle_error  # noqa: E402
from pmsmjax.assemble import spec_drive, spec_motor, with_map_aware_estimator  # noqa: E402
from pmsmjax.io.drive_files import drive_spec  # noqa: E402
from pmsmjax.io.flux_map_files import read_flux_map  # noqa: E402
from pmsmjax.scenarios import Profile, Scenario, stack_scenarios  # noqa: E402
from pmsmjax.simulate import simulate  # noqa: E402
from pmsmjax.units import rpm_to_rad_s  # noqa: E402

DRIVES = ("saturated-ipm", "pm-syrm")
OBSERVERS = ("flux-observer", "smo-pll")
SPEED_SHARES = (0.02, 0.05, 0.1, 0.2, 0.4, 0.7, 1.0, 1.5)  # of the rated speed
LOAD_SHARES = (0.0, 0.25, 0.5, 0.75, 1.0)  # of the rated torque
DURATION_S = 0.25
SCORED_S = 0.05
HOLD_DEG = 3.0
VOLTAGE_SHARE = 0.9
INITIAL_ERROR_RAD = 0.3


def operating_current(grid, pole_pairs, R, omega_e, torque, i_max, u_max, step=0.25):
    """The least current ``(2,)`` A on the map with torque ``torque`` (N m) and steady voltage within
    ``u_max`` (V) at electrical speed ``omega_e`` (rad/s), or None (brute force on a ``step`` A lattice)."""
    axis = np.arange(-i_max, i_max + step / 2, step)
    D, Q = np.meshgrid(axis, axis[axis >= 0], indexing="ij")
    keep = D * D + Q * Q <= i_max * i_max
    i = np.stack([D[keep], Q[keep]], axis=-1)
    psi, _ = grid.flux(i)
    T = 1.5 * pole_pairs * (psi[:, 0] * i[:, 1] - psi[:, 1] * i[:, 0])
    u = np.hypot(R * i[:, 0] - omega_e * psi[:, 1], R * i[:, 1] + omega_e * psi[:, 0])
    ok = (np.abs(T - torque) <= max(0.02 * abs(torque), 0.05)) & (u <= u_max)
    if not ok.any():
        return None
    k = np.flatnonzero(ok)[np.argmin(np.hypot(i[ok, 0], i[ok, 1]))]
    return i[k]


def flux_error_rate(observer, omega_e) -> float:
    """Decay rate (1/s) of the slowest linearised error pole of the flux observer at ``omega_e`` (rad/s):
    the flux error's ``s^2 + 2 sigma s + w^2`` and the angle loop's ``-alpha``."""
    sigma = float(observer.sigma0) + float(observer.zeta) * abs(omega_e)
    disc = sigma * sigma - omega_e * omega_e
    flux = sigma - math.sqrt(disc) if disc > 0 else sigma
    return min(flux, 0.5 * float(observer.k_theta))


def run_drive(name: str, observer: str, quick: bool = False) -> dict:
    spec = drive_spec(name)
    grid = read_flux_map(spec.motor["flux_map"])
    motor = spec_motor(spec)
    p = int(motor.pole_pairs)
    rated_rpm, rated_t = spec.ratings["rated_speed_rpm"], spec.ratings["rated_torque_nm"]
    i_max = spec.ratings["max_current_a"]
    u_max = VOLTAGE_SHARE * spec.inverter["u_dc_v"] / math.sqrt(3.0)
    base = spec_drive(spec, mode="current", mechanics="imposed")
    drive = with_map_aware_estimator(spec, presets.with_observer(base, observer, motor, None, startup=False))
    speeds = [s * rated_rpm for s in (SPEED_SHARES[::3] if quick else SPEED_SHARES)]
    loads = [s * rated_t for s in (LOAD_SHARES[::2] if quick else LOAD_SHARES)]
    points, scenarios = [], []
    for rpm in speeds:
        for torque in loads:
            w = rpm_to_rad_s(rpm)
            i = operating_current(grid, p, float(motor.R), p * w, torque, i_max, u_max)
            points.append((rpm, torque, i))
            if i is not None:
                scenarios.append(
                    Scenario(
                        DURATION_S,
                        speed_ref=Profile.constant(w),
                        id_ref=Profile.constant(float(i[0])),
                        iq_ref=Profile.constant(float(i[1])),
                    )
                )
    rows = []
    if scenarios:
        batch = stack_scenarios(scenarios)

        def one(s):
            init = drive.init(speed_m=s.speed_ref.values[0], theta_e=INITIAL_ERROR_RAD)
            return simulate(drive, s, initial_state=init)

        tr = eqx.filter_jit(jax.vmap(one))(batch)
        n = int(round(SCORED_S / drive.Ts))
        err = np.degrees(np.asarray(angle_error(tr.theta_e_est, tr.theta_e)))[:, -n:]
        i_peak = np.asarray(np.hypot(tr.i_dq[..., 0], tr.i_dq[..., 1])).max(axis=1)
    k = 0
    inner = drive.estimator
    for rpm, torque, i in points:
        row = {"speed_rpm": rpm, "torque_nm": torque, "i_dq_a": None if i is None else [float(x) for x in i]}
        if i is None:
            row["status"] = "unreachable"
        else:
            e = err[k]
            row.update(
                mean_deg=float(e.mean()),
                max_abs_deg=float(np.abs(e).max()),
                peak_current_a=float(i_peak[k]),
                status="holds" if np.abs(e).max() < HOLD_DEG else "fails",
            )
            w_e = p * rpm_to_rad_s(rpm)
            if observer == "flux-observer":
                row["slowest_error_rate_1_s"] = flux_error_rate(inner, w_e)
            k += 1
        rows.append(row)
    return {"drive": name, "observer": observer, "rated_speed_rpm": rated_rpm, "rated_torque_nm": rated_t,
            "speeds_rpm": speeds, "loads_nm": loads, "points": rows}  # fmt: skip


def run(quick: bool = False) -> list[dict]:
    return [run_drive(d, o, quick) for d in DRIVES for o in OBSERVERS]


def figure(results: list[dict], path) -> None:
    """One panel per drive and observer: the grid coloured by the largest angle error (degrees), a cross
    where it fails, grey where the operating point is beyond the drive's voltage or current."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(DRIVES), len(OBSERVERS), figsize=(11, 8), squeeze=False)
    for r in results:
        ax = axes[DRIVES.index(r["drive"])][OBSERVERS.index(r["observer"])]
        speeds, loads = r["speeds_rpm"], r["loads_nm"]
        z = np.full((len(loads), len(speeds)), np.nan)
        for pt in r["points"]:
            a, b = loads.index(pt["torque_nm"]), speeds.index(pt["speed_rpm"])
            if pt["status"] != "unreachable":
                z[a, b] = min(pt["max_abs_deg"], 30.0)
        im = ax.imshow(z, origin="lower", cmap="viridis_r", vmin=0.0, vmax=30.0, aspect="auto")
        ax.set_facecolor("0.85")
        for pt in r["points"]:
            a, b = loads.index(pt["torque_nm"]), speeds.index(pt["speed_rpm"])
            if pt["status"] == "fails":
                ax.plot(b, a, "rx", ms=12, mew=2)
            elif pt["status"] == "holds":
                ax.text(b, a, f"{pt['max_abs_deg']:.1f}", ha="center", va="center", fontsize=7, color="w")
        ax.set_xticks(range(len(speeds)), [f"{s:.0f}" for s in speeds], rotation=45)
        ax.set_yticks(range(len(loads)), [f"{t:.1f}" for t in loads])
        ax.set_xlabel("speed, r/min (imposed)")
        ax.set_ylabel("load torque, N m")
        ax.set_title(f"{r['drive']}: {r['observer']}", fontsize=10)
        fig.colorbar(im, ax=ax, label="largest angle error, electrical deg")
    fig.suptitle(f"Operating range on the flux maps (x: lost, beyond {HOLD_DEG:g} deg; grey: unreachable)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def format_table(results: list[dict]) -> str:
    lines = []
    for r in results:
        held = sum(pt["status"] == "holds" for pt in r["points"])
        reach = sum(pt["status"] != "unreachable" for pt in r["points"])
        lines.append(f"{r['drive']:>14} {r['observer']:>14}: holds {held} of {reach} reachable points")
        for pt in r["points"]:
            if pt["status"] == "unreachable":
                continue
            lines.append(
                f"    {pt['speed_rpm']:7.0f} r/min {pt['torque_nm']:6.2f} N m: {pt['status']:5s} "
                f"max {pt['max_abs_deg']:6.2f} deg, mean {pt['mean_deg']:+6.2f}, "
                f"peak {pt['peak_current_a']:.1f} A"
            )
    return "\n".join(lines)


#: Start-up runs: speed r/min, load N m, load time s, duration s (the ones of
#: tests/estimators/test_map_flux_observer.py).
STARTUP = {"saturated-ipm": (4500.0, 6.175, 0.3, 0.5), "pm-syrm": (2800.0, 22.4, 0.6, 1.0)}


def startup_runs(path) -> list[dict]:
    """The start-ups of ``STARTUP`` (module docstring), a figure of speed, angle error and current at
    ``path``; float32 as ``pmsmjax demo``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pmsmjax.assemble import assemble, spec_scenario, with_parts
    from pmsmjax.inverters.switching import SwitchingBridge

    jax.config.update("jax_enable_x64", False)
    rows = []
    fig, axes = plt.subplots(3, len(STARTUP), figsize=(11, 8), sharex="col", squeeze=False)
    for col, (name, (rpm, load, t_load, duration)) in enumerate(STARTUP.items()):
        spec = drive_spec(name)
        c = spec.control
        end = (c["handover_speed_rad_s"] + c["blend_speed_rad_s"]) / c["startup_acceleration_rad_s2"]
        for observer in OBSERVERS:
            for bridge in ("averaged", "switching"):
                drive = assemble(spec, "pi", estimator=observer)
                if bridge == "switching":
                    drive = with_parts(drive, {"bridge": SwitchingBridge(drive.bridge.u_dc)})
                tr = simulate(drive, spec_scenario(spec, rpm, load, t_load, duration)).to_numpy()
                t = np.asarray(tr.t)
                e = np.degrees(np.asarray(angle_error(tr.theta_e_est, tr.theta_e)))
                i = np.hypot(tr.i_dq[:, 0], tr.i_dq[:, 1])
                rows.append(
                    {
                        "drive": name,
                        "observer": observer,
                        "bridge": bridge,
                        "handover_end_s": end,
                        "peak_current_a": float(i.max()),
                        "limit_a": float(drive.controller.current_limit),
                        "max_error_after_handover_deg": float(np.abs(e[t > end + 0.02]).max()),
                        "steady_error_under_load_deg": float(np.abs(e[t > duration - 0.1]).max()),
                        "final_speed_rpm": float(tr.omega_m[-1] * 30.0 / math.pi),
                    }  # fmt: skip
                )
                if bridge == "averaged":
                    ax = axes[:, col]
                    ax[0].plot(t, tr.omega_m * 30.0 / math.pi, label=observer)
                    ax[1].plot(t, np.clip(e, -30.0, 30.0), label=observer)
                    ax[2].plot(t, i, label=observer)
        axes[0, col].set_title(f"{name}: {rpm:.0f} r/min, {load:g} N m at {t_load:g} s", fontsize=10)
        axes[0, col].set_ylabel("speed, r/min")
        axes[1, col].set_ylabel("angle error, el. deg (clipped at 30)")
        axes[1, col].axvline(end, color="0.5", ls=":")
        axes[2, col].set_ylabel("current |i|, A")
        axes[2, col].axhline(float(drive.controller.current_limit), color="r", ls="--", lw=0.8)
        axes[2, col].set_xlabel("time, s")
        axes[0, col].legend(fontsize=8)
    fig.suptitle("Start from standstill (I/f; hand-over ends at the dotted line), averaged bridge")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", help="write the results here")
    parser.add_argument("--figure", default="docs/assets/ch05_map_observer_range.png")
    parser.add_argument("--quick", action="store_true", help="a coarse grid")
    parser.add_argument("--startup", action="store_true", help="the start-ups instead of the grid")
    args = parser.parse_args()
    if args.startup:
        rows = startup_runs(args.figure)
        for r in rows:
            print(
                f"{r['drive']:>14} {r['observer']:>14} {r['bridge']:>9}: peak {r['peak_current_a']:.1f} A "
                f"(limit {r['limit_a']:g}), after hand-over max {r['max_error_after_handover_deg']:.2f} deg, "
                f"under load {r['steady_error_under_load_deg']:.2f} deg, {r['final_speed_rpm']:.0f} r/min"
            )
        if args.json:
            with open(args.json, "w") as f:
                json.dump(rows, f, indent=1)
        return
    results = run(args.quick)
    print(format_table(results))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=1)
    figure(results, args.figure)


if __name__ == "__main__":
    main()
