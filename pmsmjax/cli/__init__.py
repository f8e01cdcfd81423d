"""The ``pmsmjax`` command: ``demo`` (alias ``simulate``), ``replay``, ``tune``, ``bench``, ``pwm-compare``,
``identify`` and ``montecarlo``.

Every subcommand checks its input before compiling anything and writes each output file atomically
(temporary file in the same folder, then rename), so an interrupted or failed run leaves no half file.
"""

import argparse
import json
import sys
import time
from pathlib import Path

from .validation import ParameterError


def _add_demo_parser(sub):
    p = sub.add_parser(
        "demo",
        aliases=["simulate"],
        help="run the book's FOC scenario and write figures, a trace and summary.json",
        description=(
            "Simulate the book drive (design-rule PI gains, SVPWM, averaged bridge, 10 kHz): a speed step "
            "from rest, then a load step. Writes DIR/trace.csv (or .npz), DIR/summary.json and PNG figures."
        ),
    )
    p.add_argument("--out", default="demo_out", help="output folder (created), default: demo_out")
    p.add_argument("--motor", default="book", help="preset name (book, book_salient) or motor TOML file")
    p.add_argument("--speed-rpm", type=float, default=1000.0, help="speed step, r/min (default 1000)")
    p.add_argument("--load-nm", type=float, default=10.0, help="load step, N m (default 10)")
    p.add_argument("--load-time-s", type=float, default=0.2, help="time of the load step, s (default 0.2)")
    p.add_argument("--duration-s", type=float, default=0.4, help="simulated time, s (default 0.4)")
    p.add_argument("--frame", choices=["dq", "alpha_beta", "abc"], default="dq", help="machine model frame")
    p.add_argument("--substeps", type=int, default=10, help="RK4 sub-steps per 100 us period (default 10)")
    p.add_argument("--no-delay", action="store_true", help="no one-period computational delay")
    p.add_argument("--current-bandwidth", type=float, default=1100.0, help="current loop a_c, rad/s")
    p.add_argument("--speed-bandwidth", type=float, default=50.0, help="speed loop beta, rad/s")
    p.add_argument("--decimate", type=int, default=1, help="record every N-th period (default 1)")
    p.add_argument("--format", choices=["csv", "npz"], default="csv", help="trace file format")
    p.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    p.set_defaults(func=_cmd_demo)


def _cmd_demo(args) -> int:
    import jax

    from . import presets
    from .logs import atomic_write, write_csv_atomic
    from .plotting import save_demo_figures
    from .simulate import check_simulation, simulate
    from .summary import speed_step_summary

    motor = presets.load_motor(args.motor)
    drive = presets.book_drive(
        motor,
        frame=args.frame,
        n_substeps=args.substeps,
        computation_delay=not args.no_delay,
        current_bandwidth=args.current_bandwidth,
        speed_bandwidth=args.speed_bandwidth,
    )
    scenario = presets.book_scenario(args.speed_rpm, args.load_nm, args.load_time_s, args.duration_s)
    check_simulation(drive, scenario, args.decimate)

    t0 = time.perf_counter()
    trace = jax.block_until_ready(simulate(drive, scenario, decimate=args.decimate))
    first_call_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    trace = jax.block_until_ready(simulate(drive, scenario, decimate=args.decimate))
    run_s = time.perf_counter() - t0

    load_time = args.load_time_s if 0 < args.load_time_s < args.duration_s else None
    summary = {
        "scenario": {
            "speed_rpm": args.speed_rpm,
            "load_nm": args.load_nm,
            "load_time_s": args.load_time_s,
            "duration_s": args.duration_s,
        },
        "drive": {
            "motor": args.motor,
            "frame": args.frame,
            "Ts_s": drive.Ts,
            "n_substeps": drive.n_substeps,
            "computation_delay": drive.computation_delay,
            "current_bandwidth_rad_s": args.current_bandwidth,
            "speed_bandwidth_rad_s": args.speed_bandwidth,
            "current_limit_a": float(drive.controller.current_limit),
            "u_dc_v": float(drive.bridge.u_dc),
        },
        "metrics": speed_step_summary(
            trace, load_time_s=load_time, current_limit_a=float(drive.controller.current_limit)
        ),
        "timing": {"compile_s": max(first_call_s - run_s, 0.0), "run_s": run_s},
    }

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    columns = trace.columns()
    if args.format == "csv":
        write_csv_atomic(out / "trace.csv", columns)
    else:
        atomic_write(out / "trace.npz", lambda f: __import__("numpy").savez(f, **columns))
    atomic_write(out / "summary.json", lambda f: f.write(json.dumps(summary, indent=2).encode()))
    figures = [] if args.no_figures else save_demo_figures(trace, out, "pmsmjax demo: book FOC drive")
    m = summary["metrics"]
    print(
        f"final speed {m['final_speed_rpm']:.1f} r/min (ref {m['reference_speed_rpm']:.0f}), "
        f"rise {_fmt(m['rise_time_s'], 1e3)} ms, overshoot {m['overshoot_pct']:.2f} %, "
        f"settling {_fmt(m['settling_time_s'], 1e3)} ms"
    )
    if "speed_dip_rpm" in m:
        print(
            f"load step: dip {m['speed_dip_rpm']:.1f} r/min, recovery {_fmt(m['recovery_time_s'], 1e3)} ms; "
            f"peak current {m['peak_phase_current_a']:.2f} A (limit {m['current_limit_a']:.1f} A)"
        )
    print(f"compile {summary['timing']['compile_s']:.2f} s, run {summary['timing']['run_s'] * 1e3:.1f} ms")
    print(
        f"wrote {out}/trace.{args.format}, {out}/summary.json"
        + (f" and {len(figures)} figures" if figures else "")
    )
    return 0


def _fmt(x, scale):
    return "n/a" if x is None else f"{x * scale:.1f}"


def _add_replay_parser(sub):
    p = sub.add_parser(
        "replay",
        help="run the machine under a recorded voltage sequence",
        description=(
            "Replay a log (CSV/NPZ/MAT) with columns time,u_d,u_q and optionally omega_m (imposed speed, "
            "mechanical rad/s), T_L (N m). Row k's voltage is held until row k+1. Writes DIR/replay.csv "
            "with time,i_d,i_q,omega_m,theta_e (row k = state at row k's time)."
        ),
    )
    p.add_argument("log", help="log file (.csv, .npz or .mat)")
    p.add_argument("--motor", required=True, help="preset name (book, book_salient) or motor TOML file")
    p.add_argument("--out", required=True, help="output folder (created)")
    p.add_argument(
        "--hold",
        choices=["rotor", "stator"],
        default="rotor",
        help="frame the voltage is held in between rows: rotor (dq-model simulators, default) or stator "
        "(a real inverter)",
    )
    p.add_argument("--substeps", type=int, default=None, help="RK4 steps per row (default: automatic)")
    p.set_defaults(func=_cmd_replay)


def _cmd_replay(args) -> int:
    from .replay import replay_file

    path = replay_file(args.log, args.motor, args.out, hold=args.hold, n_substeps=args.substeps)
    print(f"wrote {path}")
    return 0


def _add_bench_parser(sub):
    p = sub.add_parser(
        "bench",
        help="measure simulation speed, compile and gradient time (benchmarks/bench_core.py)",
        description="Speed of the book drive simulation against a minimal hand-written loop, same run.",
    )
    p.add_argument("--json", default=None, help="write the results to this JSON file")
    p.add_argument("--quick", action="store_true", help="small sizes (a smoke run)")
    p.set_defaults(func=_cmd_bench)


def _cmd_bench(args) -> int:
    from benchmarks.bench_core import main as bench_main

    bench_main(args.json, quick=args.quick)
    return 0


def _add_tune_parser(sub):
    p = sub.add_parser(
        "tune",
        help="tune the FOC gains by gradients over a batch of speed/load scenarios",
        description=(
            "Gradient auto-tuning of the book drive's speed and current PI gains (BFGS or Adam in log-space "
            "from the design-rule gains) over a seeded batch of speed steps (200-1500 r/min, both "
            "directions) and load steps (0-10 N m), checked on a held-out batch. Writes DIR/gains.toml, "
            "DIR/result.json, DIR/cost.png, DIR/responses.png and DIR/checkpoint.npz; running it again "
            "resumes. Settings: flags, then --config TOML ([weights], [tune], [job] tables), then built-in "
            "defaults."
        ),
    )
    p.add_argument("--out", default="tune_out", help="output folder (created), default: tune_out")
    p.add_argument("--config", default=None, help="TOML with [weights], [tune] and [job] tables")
    p.add_argument("--iterations", type=int, help="maximum iterations (default 100)")
    p.add_argument("--train", type=int, help="training scenarios (default 64)")
    p.add_argument("--heldout", type=int, help="held-out scenarios (default 64)")
    p.add_argument("--seed", type=int, help="seed of the training batch (default 0; held-out: seed + 1)")
    p.add_argument(
        "--duration-s", type=float, nargs=2, metavar=("LOW", "HIGH"), help="scenario durations, s (0.3 0.5)"
    )
    p.add_argument(
        "--gains", nargs="+", help="gains to tune: aliases speed, current or names like controller.speed.kp"
    )
    p.add_argument(
        "--method",
        choices=("adam", "bfgs"),
        help="optimiser: bfgs (default; step-capped quasi-Newton on the cost with its penalty kinks rounded) "
        "or adam",
    )
    p.add_argument("--learning-rate", type=float, help="Adam step in log-space (default 0.08)")
    p.add_argument("--substeps", type=int, help="RK4 sub-steps while tuning (default 1)")
    p.add_argument("--eval-substeps", type=int, help="RK4 sub-steps for before/after figures (default 10)")
    p.add_argument("--time-budget-s", type=float, help="stop after this wall time, s")
    p.add_argument("--fresh", action="store_true", help="ignore and replace an existing checkpoint")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_tune)


def _cmd_tune(args) -> int:
    # The command line is the one place where pmsmjax reaches up into the tuning workflows.
    import dataclasses

    from tuning.autotune.job import DEFAULT_CONFIG, read_tune_toml, run_tune_job

    kwargs = read_tune_toml(args.config) if args.config else {}
    config = kwargs.pop("config", DEFAULT_CONFIG)
    overrides = {
        "names": tuple(args.gains) if args.gains else None,
        "method": args.method,
        "learning_rate": args.learning_rate,
        "max_iterations": args.iterations,
        "time_budget_s": args.time_budget_s,
    }
    config = dataclasses.replace(config, **{k: v for k, v in overrides.items() if v is not None})
    for key, value in (
        ("n_train", args.train),
        ("n_heldout", args.heldout),
        ("train_seed", args.seed),
        ("heldout_seed", None if args.seed is None else args.seed + 1),
        ("duration_s", tuple(args.duration_s) if args.duration_s else None),
        ("tune_substeps", args.substeps),
        ("eval_substeps", args.eval_substeps),
    ):
        if value is not None:
            kwargs[key] = value
    checkpoint = Path(args.out) / "checkpoint.npz"
    if args.fresh and checkpoint.exists():
        checkpoint.unlink()
    data = run_tune_job(args.out, config=config, progress=not args.no_progress, **kwargs)
    tr, ho = data["train"], data["heldout"]
    cut = lambda d: 100.0 * (1.0 - d["after"]["itae"] / d["before"]["itae"])
    if data["resumed_from_iteration"]:
        print(f"resumed from iteration {data['resumed_from_iteration']}")
    print(
        f"train ITAE {tr['before']['itae']:.4f} -> {tr['after']['itae']:.4f} ({cut(tr):.1f} % lower), "
        f"held-out {ho['before']['itae']:.4f} -> {ho['after']['itae']:.4f} ({cut(ho):.1f} % lower)"
    )
    print(
        f"overshoot {tr['before']['overshoot_pct']:.3f} -> {tr['after']['overshoot_pct']:.3f} % "
        f"(train mean), peak current {tr['after']['max_peak_current_a']:.2f} A, "
        f"scenarios over the limit: {tr['after']['scenarios_over_current_limit']}"
    )
    print(
        f"{data['iterations']} iterations ({data['stopped']}), wall {data['wall_time_s']:.1f} s "
        f"(compile {data['compile_time_s']:.1f} s); wrote {args.out}/gains.toml, result.json, figures"
    )
    return 0


def _add_pwm_compare_parser(sub):
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
    p.set_defaults(func=_cmd_pwm_compare)


def _cmd_pwm_compare(args) -> int:
    import numpy as np

    from .logs import atomic_write
    from .pwm_compare import CompareSettings, compare

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
        from .plotting import save_figure
        from .plotting_pwm import spectrum_figure, thd_figure, waveform_figure

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


def _add_identify_parser(sub):
    p = sub.add_parser(
        "identify",
        help="identify R, L_d, L_q, psi_f, J, B with error bars from a logged drive run",
        description=(
            "Fit the PMSM model to a log (CSV/NPZ/MAT; default columns time,u_d,u_q,i_d,i_q,omega_m and "
            "optionally theta_e, T_L; alpha-beta/abc/duty voltages and alpha-beta/abc currents with theta_e) "
            "by output-error Levenberg-Marquardt over shooting windows. Writes DIR/params.json (value, "
            "stderr, ci95, identifiable per parameter; residuals; wall time) and DIR/fit.png."
        ),
    )
    p.add_argument("log", help="log file (.csv, .npz or .mat)")
    p.add_argument("--out", required=True, help="output folder (created)")
    p.add_argument("--pole-pairs", type=int, required=True, help="number of pole pairs (known)")
    p.add_argument("--config", default=None, help="TOML with [columns], [units], [log], [identify] tables")
    p.add_argument(
        "--columns", nargs="+", default=[], metavar="CANONICAL=NAME", help="column map, e.g. u_d=Ud"
    )
    p.add_argument("--units", nargs="+", default=[], metavar="COLUMN=UNIT", help="e.g. omega_m=rpm time=ms")
    p.add_argument(
        "--hold",
        choices=["stator", "rotor"],
        default=None,
        help="how the logged voltage was held between rows: stator (real inverter, default) or rotor "
        "(dq-model simulator)",
    )
    p.add_argument("--u-dc", type=float, default=None, help="DC-link voltage, V, for duty logs without U_dc")
    p.add_argument("--resample", action="store_true", help="resample an irregular time grid (with a warning)")
    p.add_argument("--fix", nargs="+", default=[], metavar="NAME=VALUE", help="hold parameters fixed (SI)")
    p.add_argument(
        "--load", choices=["constant", "none"], default=None, help="estimate a constant load torque"
    )
    p.add_argument("--dead-time", action="store_true", help="estimate an inverter dead-time voltage V_dt")
    p.add_argument("--no-figures", action="store_true", help="do not write fit.png")
    p.set_defaults(func=_cmd_identify)


def _pairs(items, what, convert=str):
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise ParameterError(f"{what}: {item!r} is not KEY=VALUE.")
        try:
            out[key.strip()] = convert(value.strip())
        except ValueError as err:
            raise ParameterError(f"{what}: {item!r}: {err}.") from err
    return out


def _cmd_identify(args) -> int:
    # The command line is the one place where pmsmjax reaches up into the tuning workflows.
    from tuning.identify import identify_file

    options = {"fixed": _pairs(args.fix, "--fix", float)} if args.fix else {}
    if args.load:
        options["load"] = args.load
    if args.dead_time:
        options["dead_time"] = True
    result = identify_file(
        args.log,
        args.out,
        args.pole_pairs,
        config=args.config,
        columns=_pairs(args.columns, "--columns"),
        units=_pairs(args.units, "--units"),
        hold=args.hold,
        u_dc=args.u_dc,
        resample=args.resample,
        figures=not args.no_figures,
        **options,
    )
    s = result.summary
    for name, p in s["parameters"].items():
        ci = p["ci95"]
        interval = f"[{ci[0]:.5g}, {ci[1]:.5g}]" if ci[0] is not None else "[not determined]"
        flag = "" if p["identifiable"] is not False else "  NOT IDENTIFIABLE"
        print(f"{name:6s} {p['value']:.6g} {p['unit']:10s} 95 % {interval}{flag}")
    for name, advice in s["identifiability"]["advice"].items():
        print(f"to determine {name}: {advice}")
    print(
        f"wall time {s['wall_time_s']:.2f} s; wrote {args.out}/params.json"
        + ("" if args.no_figures else ", fit.png")
    )
    return 0


def _add_montecarlo_parser(sub):
    p = sub.add_parser(
        "montecarlo",
        help="Monte Carlo robustness study of the book drive over parameter tolerances",
        description=(
            "Run N closed-loop runs of the book scenario (1000 r/min step, 10 N m load step at 0.2 s, "
            "0.4 s, 10 kHz, 10 sub-steps) with the plant's R, L_d, L_q, psi_f, J, B and the DC link drawn "
            "from their tolerances (default: R +-20 %, L +-15 %, psi_f +-10 %, J +-50 %, B +-50 %, "
            "U_dc +-10 %, uniform), "
            "chunked and sharded over every device. Writes DIR/summary.json (percentiles, failure rates, "
            "CVaR, AD sensitivities, Spearman ranks, run and compile time), DIR/histograms.png, "
            "DIR/fan_chart.png, DIR/tornado.png and DIR/chunks/*.npz; running it again resumes. Settings: "
            "flags, then --config TOML ([study], [drive], [scenario], [thresholds], [parameters.NAME])."
        ),
    )
    p.add_argument("--n", type=int, help="number of runs (default 1000)")
    p.add_argument("--out", default="montecarlo_out", help="output folder (created), default: montecarlo_out")
    p.add_argument("--config", default=None, help="study TOML (see tuning/montecarlo/study.py)")
    p.add_argument("--seed", type=int, help="sampling seed (default 0)")
    p.add_argument("--chunk-size", type=int, help="runs per chunk (default 2048)")
    p.add_argument("--latin-hypercube", action="store_true", help="Latin hypercube sampling")
    p.add_argument("--clip", action="store_true", help="clip non-physical samples instead of refusing")
    p.add_argument("--sensitivity-runs", type=int, help="runs differentiated by forward-mode AD (256)")
    p.add_argument("--devices", type=int, help="CPU only: split the CPU into this many devices (cores)")
    p.add_argument(
        "--distributed", action="store_true", help="multi-host: call jax.distributed.initialize() first"
    )
    p.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_montecarlo)


def _cmd_montecarlo(args) -> int:
    # Split the CPU into one device per core before anything initialises JAX's backends.
    from tuning.montecarlo.cpu_devices import split_cpu

    if args.distributed:
        import jax

        jax.distributed.initialize()  # cluster settings from the environment (SLURM, Cloud TPU, ...)
    else:
        split_cpu(args.devices)
    from tuning.montecarlo import run_study
    from tuning.montecarlo.study import Study, read_study_toml

    kwargs = read_study_toml(args.config) if args.config else {}
    for key, value in (
        ("n", args.n),
        ("seed", args.seed),
        ("chunk_size", args.chunk_size),
        ("sensitivity_runs", args.sensitivity_runs),
        ("sampling", "latin_hypercube" if args.latin_hypercube else None),
        ("nonphysical", "clip" if args.clip else None),
    ):
        if value is not None:
            kwargs[key] = value
    s = run_study(Study(**kwargs), args.out, progress=not args.no_progress, figures=not args.no_figures)
    if s is None:  # not process 0 of a multi-host run: it only computed its shards
        return 0
    f, m = s["failures"], s["metrics"]
    ch = s["chunks"]
    print(
        f"{s['n_runs']} runs on {s['devices']['count']} device(s): run {s['run_time_s']:.2f} s "
        f"({ch['computed_now']} chunks computed, {ch['loaded']} loaded), compile {s['compile_time_s']:.1f} s"
    )
    for name in ("itae", "overshoot_pct", "settling_time_s", "dip_rpm", "peak_current_a"):
        st = m[name]
        if st["n"]:
            print(f"  {name:16s} p5 {st['p5']:.4g}  p50 {st['p50']:.4g}  p95 {st['p95']:.4g} {st['unit']}")
    print(
        f"failures: {100 * f['any']['rate']:.2f} % (current {f['current_limit']['count']}, tracking "
        f"{f['speed_tracking']['count']}, unstable {f['unstable']['count']}); wrote {args.out}/summary.json"
    )
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pmsmjax", description="Differentiable, batched PMSM drive simulation in JAX."
    )
    sub = parser.add_subparsers(dest="command", required=True)
    _add_demo_parser(sub)
    _add_replay_parser(sub)
    _add_bench_parser(sub)
    _add_tune_parser(sub)
    _add_pwm_compare_parser(sub)
    _add_identify_parser(sub)
    _add_montecarlo_parser(sub)
    return parser


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except ParameterError as err:
        print(f"pmsmjax {args.command}: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
