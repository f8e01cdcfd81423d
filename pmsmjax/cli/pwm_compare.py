"""``pmsmjax pwm-compare``: the PWM methods compared at one steady operating point
(:mod:`pmsmjax.pwm_compare`)."""

import json
import time
from pathlib import Path


def add_parser(sub):
    p = sub.add_parser(
        "pwm-compare",
        help="compare the PWM methods (spectra, THD, DC-bus utilisation) at one steady operating point",
        description=(
            "Book chapter 2: sinusoidal PWM, third-harmonic and min-max injection and SVPWM at one steady "
            "operating point of the book drive (reached through the book scenario), each with the averaged "
            "bridge, the switching-resolved bridge, and the switching bridge with dead time. Writes "
            "DIR/pwm.json (per variant: linear_limit_v, fundamental, voltage and current THD, DC-bus "
            "utilisation against sinusoidal PWM), DIR/waveforms.npz and PNG figures."
        ),
    )
    p.add_argument("--out", default="pwm_out", help="output folder (created), default: pwm_out")
    p.add_argument("--speed-rpm", type=float, default=1000.0, help="speed, r/min (f_sw/f_1 whole; 1000)")
    p.add_argument("--load-nm", type=float, default=10.0, help="load torque, N m (default 10)")
    p.add_argument("--dead-time-us", type=float, default=2.0, help="dead time of the _deadtime variants, us")
    p.add_argument("--settle-cycles", type=int, default=2, help="fundamental periods settled (default 2)")
    p.add_argument("--window-cycles", type=int, default=2, help="fundamental periods analysed (default 2)")
    p.add_argument(
        "--modulators",
        nargs="+",
        default=["sinusoidal", "third_harmonic", "min_max", "svpwm"],
        help="modulators to compare (default: all four)",
    )
    p.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    p.set_defaults(func=run)


def run(args) -> int:
    import numpy as np

    from ..logs import atomic_write
    from ..pwm_compare import CompareSettings, compare

    settings = CompareSettings(
        speed_rpm=args.speed_rpm,
        load_nm=args.load_nm,
        dead_time_s=args.dead_time_us * 1e-6,
        settle_cycles=args.settle_cycles,
        window_cycles=args.window_cycles,
        modulators=tuple(args.modulators),
    )
    t0 = time.perf_counter()
    result = compare(settings, progress=print)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    report = {"settings": result["settings"], "entries": result["entries"]}
    report["wall_time_s"] = time.perf_counter() - t0
    atomic_write(out / "pwm.json", lambda f: f.write(json.dumps(report, indent=2).encode()))
    arrays = {f"{name}/{key}": v for name, w in result["waves"].items() for key, v in w.items()}
    atomic_write(out / "waveforms.npz", lambda f: np.savez(f, **arrays))
    written = ["pwm.json", "waveforms.npz"]
    if not args.no_figures:
        from ..plotting import save_figure
        from ..plotting_pwm import spectrum_figure, thd_figure, waveform_figure

        shown = [m + "_switching" for m in ("sinusoidal", "svpwm") if m in settings.modulators]
        for name, fig in (
            ("pwm_waveforms.png", waveform_figure(result, shown)),
            ("pwm_spectra.png", spectrum_figure(result, shown)),
            ("pwm_thd.png", thd_figure(result)),
        ):
            save_figure(fig, out / name)
            written.append(name)
    print(f"wrote {', '.join(f'{out}/{w}' for w in written)} in {report['wall_time_s']:.1f} s")
    return 0
