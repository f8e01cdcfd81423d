"""The linearised sampled-data loops against a sine sweep of the nonlinear drive, their margins, and what the
margins cost per call.

For the book drive and the two-mass servo (``servo-two-mass``), at an operating point inside the limits:

- the current loop (q axis, broken at the measured current, speed loop open) and the speed loop (broken at
  the q-current reference, current loop closed) linearised by ``jax.jacfwd`` of the period map
  ([`pmsmjax.analysis.loop_linearisation`][pmsmjax.analysis.loop_linearisation]);
- the same loops measured on the nonlinear simulation by a sine injected at the break point and correlated
  ([`pmsmjax.analysis.loop_sweep`][pmsmjax.analysis.loop_sweep]), at frequencies up to a fifth of the control
  rate: the largest magnitude (dB) and phase (deg) differences;
- the margins ([`pmsmjax.analysis.margins`][pmsmjax.analysis.margins]): crossover, bandwidth, phase and gain
  margins, sensitivity peak;
- the cost of one linearisation and margins call (compile and run, float32 and float64), and of its gradient.

A Bode figure per drive (``loop_margins_<drive>.png``): ``|L|`` and ``arg L`` of both loops, linearised
(lines) and swept (markers), the crossovers and phase margins marked.

``python -m benchmarks.loop_margins [--points 14] [--folder loop_margins_out] [--json FILE]``
"""

import argparse
import time
from pathlib import Path

import numpy as np

from benchmarks.bench_core import machine_info, publish

#: (preset, speed rad/s mechanical, load N m): inside the voltage and current limits.
DRIVES = (("book", 90.0, 5.0), ("servo-two-mass", 35.0, 0.7))
#: Injected amplitude, A.
AMPLITUDE_A = 0.1


def timed(f, *args):
    start = time.perf_counter()
    out = f(*args)
    import jax

    jax.block_until_ready(out)
    return out, time.perf_counter() - start


def cost(preset, speed, load) -> dict:
    """Seconds to compile and to run the linearisation and both loops' margins, and its gradient in the
    speed PI's ``kp``, in the drive's float32 (what tune and montecarlo use)."""
    import equinox as eqx
    import jax
    import jax.numpy as jnp

    from pmsmjax.analysis.loop_linearisation import linearise_traced
    from pmsmjax.analysis.margins import loop_margins
    from pmsmjax.assemble import spec_drive
    from pmsmjax.io.drive_files import drive_spec

    drive = spec_drive(drive_spec(preset), "pi")

    def pm(kp):
        d = eqx.tree_at(lambda d: d.controller.speed.kp, drive, kp)
        lin = linearise_traced(d, jnp.asarray(speed, jnp.float32), jnp.asarray(load, jnp.float32))
        return loop_margins(lin, "speed").phase_margin_deg + loop_margins(lin, "current").phase_margin_deg

    out = {}
    kp = drive.controller.speed.kp
    for name, f in (("margins", jax.jit(pm)), ("gradient", jax.jit(jax.grad(pm)))):
        _, first = timed(f, kp)
        _, again = timed(f, kp * 1.01)
        out[f"{name}_compile_s"] = first - again
        out[f"{name}_run_s"] = again
    return out


def run(points: int, folder: Path) -> dict:
    import jax

    jax.config.update("jax_enable_x64", True)
    from pmsmjax.analysis.loop_linearisation import linearise
    from pmsmjax.analysis.loop_sweep import sweep_loop
    from pmsmjax.analysis.margins import drive_margins
    from pmsmjax.assemble import spec_drive
    from pmsmjax.io.drive_files import drive_spec

    results = {}
    for preset, speed, load in DRIVES:
        drive = spec_drive(drive_spec(preset), "pi")
        lin = linearise(drive, speed, load)
        entry = {"operating_point": {"speed_rad_s": speed, "load_nm": load}}
        entry["margins"] = drive_margins(drive, speed, load)
        fs = 1.0 / drive.Ts
        curves = {}
        for loop in ("current", "speed"):
            start = time.perf_counter()
            f, measured = sweep_loop(
                drive, loop, speed, load, np.geomspace(10.0, fs / 5, points), AMPLITUDE_A
            )
            sweep_s = time.perf_counter() - start
            model = np.asarray(lin.loop_transfer(loop, f))
            ratio = measured / model
            entry[loop] = {
                "frequencies_hz": f.tolist(),
                "max_abs_db": float(np.max(np.abs(20 * np.log10(np.abs(ratio))))),
                "max_abs_deg": float(np.max(np.abs(np.degrees(np.angle(ratio))))),
                "sweep_s": sweep_s,
            }
            curves[loop] = (f, measured)
        entry["figure"] = str(bode_figure(preset, lin, curves, entry["margins"], folder))
        results[preset] = entry
    jax.config.update("jax_enable_x64", False)
    for preset, speed, load in DRIVES:
        results[preset]["cost_float32"] = cost(preset, speed, load)
    return {"drives": results, "amplitude_a": AMPLITUDE_A, "machine": machine_info()}


def bode_figure(preset, lin, curves, margins, folder: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pmsmjax.analysis.margins import frequency_grid

    f = frequency_grid(lin.Ts, 600, 1.0)
    fig, (ax_m, ax_p) = plt.subplots(2, 1, figsize=(8, 6.5), sharex=True)
    for loop, color in (("current", "tab:blue"), ("speed", "tab:orange")):
        L = np.asarray(lin.loop_transfer(loop, f))
        fm, Lm = curves[loop]
        ax_m.semilogx(f, 20 * np.log10(np.abs(L)), color=color, label=f"{loop} loop, linearised")
        ax_m.semilogx(
            fm, 20 * np.log10(np.abs(Lm)), "o", color=color, mfc="none", label=f"{loop} loop, sine sweep"
        )
        ax_p.semilogx(f, np.degrees(np.unwrap(np.angle(L))), color=color)
        ax_p.semilogx(fm, np.degrees(np.unwrap(np.angle(Lm))), "o", color=color, mfc="none")
        m = margins[loop]
        if m["crossover_hz"] is not None:
            ax_m.axvline(m["crossover_hz"], color=color, ls=":", lw=1)
            ax_p.axvline(m["crossover_hz"], color=color, ls=":", lw=1)
            ax_p.annotate(
                f"{loop}: first crossover {m['crossover_hz']:.3g} Hz, PM {m['phase_margin_deg']:.1f} deg "
                f"(least over the crossovers), Ms {m['sensitivity_peak']:.2f}",
                xy=(m["crossover_hz"], -180.0 + m["phase_margin_deg"]),
                xytext=(5, -20 if loop == "speed" else 15),
                textcoords="offset points",
                color=color,
                fontsize=8,
            )
    ax_m.axhline(0.0, color="k", lw=0.8)
    ax_p.axhline(-180.0, color="k", lw=0.8)
    ax_m.set(ylabel="|L| / dB", title=f"{preset}: loop transfers at the operating point (dotted: crossovers)")
    ax_p.set(xlabel="f / Hz", ylabel="arg L / deg")
    ax_m.legend(fontsize=8, loc="lower left")
    for ax in (ax_m, ax_p):
        ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"loop_margins_{preset}.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def format_table(r: dict) -> str:
    lines = []
    for preset, e in r["drives"].items():
        lines.append(
            f"{preset} at {e['operating_point']}: spectral radius {e['margins']['spectral_radius']:.5f}"
        )
        for loop in ("current", "speed"):
            m = e["margins"][loop]
            lines.append(
                f"  {loop:<8} sweep vs linearised: max {e[loop]['max_abs_db']:.4f} dB, "
                f"{e[loop]['max_abs_deg']:.3f} deg | crossover {m['crossover_hz']:.4g} Hz, "
                f"bandwidth {m['bandwidth_hz']:.4g} Hz, PM "
                f"{m['phase_margin_deg']:.1f} deg, GM {m['gain_margin_db']:.1f} dB, "
                f"Ms {m['sensitivity_peak']:.3f}"
            )
        c = e["cost_float32"]
        lines.append(
            f"  cost (float32): margins compile {c['margins_compile_s']:.1f} s, "
            f"run {c['margins_run_s'] * 1e3:.1f} ms; gradient compile {c['gradient_compile_s']:.1f} s, "
            f"run {c['gradient_run_s'] * 1e3:.1f} ms"
        )
    return "\n".join(lines)


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--points", type=int, default=14)
    p.add_argument("--folder", default="loop_margins_out")
    p.add_argument("--json", default=None)
    a = p.parse_args(argv)
    results = run(a.points, Path(a.folder))
    return publish(results, format_table(results), a.json)


if __name__ == "__main__":
    main()
