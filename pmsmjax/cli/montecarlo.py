"""``pmsmjax montecarlo``: a Monte Carlo robustness study of the user's drive (a drive file or preset,
``--motor``; [`tuning.montecarlo`][tuning.montecarlo])."""

import argparse
import os
import textwrap

from pmsmjax.cli import checks, drive_flags, memory
from pmsmjax.cli.gains import add_gains_flag, read_gains_flag
from pmsmjax.spec import registry
from pmsmjax.spec.validation import ParameterError

#: The study TOML, as ``pmsmjax montecarlo --help`` shows it (the layout of tuning/montecarlo/study.py).
STUDY_TOML = """\
study TOML (--config; every table and key optional, flags win over it):

  [study]       n = 1000, seed = 0, sampling = "random" | "latin_hypercube", chunk_size = "auto" | N,
                nonphysical = "refuse" | "clip", decimate = 40, sensitivity_runs = 256
  [drive]       motor = "book" (preset or drive file; --motor wins), gains = "tune_out/gains.toml" (relative
                to this file), current_bandwidth (rad/s), speed_bandwidth (rad/s), current_limit (A),
                u_dc (V) (default: the drive file's; book: 1100, 50, 15, 311), n_substeps = 10,
                unroll_substeps = false, estimator = "smo" (a chapter 5 observer; default: the exact
                sensor)
  [scenario]    speed_rpm, load_nm, load_time_s, duration_s (default: the drive file's [scenario];
                book: 1000.0, 10.0, 0.2, 0.4)
  [thresholds]  current_a (A; default 1.05 x the current limit), tracking_rpm = 10.0
  [parameters."motor.R"]   distribution = "uniform" | "normal" | "lognormal", tolerance = 0.2 (+-20 %),
                           sigmas = 3.0, nominal = ... (default: the drive's own value)

  Parameter names: motor.R, motor.L_d, motor.L_q, motor.psi_f, motor.J, motor.B (the plant's; six- and
  five-phase also motor.L_ls), bridge.u_dc, controller.<path> (e.g. controller.speed.kp),
  scenario.speed_rpm, scenario.load_nm. A [parameters] table replaces the default set as a whole: the
  drive file's [tolerances] (book: R 20 %, L_d/L_q 15 %, psi_f 10 %, J/B 50 %, u_dc 10 %), or that book
  set for a file without one.

  Sensorless (--estimator NAME): the drive runs on that observer from standstill (the drive file's I/f
  start, [control] startup_*). The observer
  and the controller keep the nominal motor; the plant's R, L_d, L_q, psi_f are drawn (default R +-30 %,
  L_d, L_q +-20 % each, psi_f +-10 %, uniform). Adds per run the angle error RMS and max and the speed
  estimation error RMS after 50 ms, and loss of lock (out of lock, |angle error| > 90 el. deg or
  |speed estimate error| > 50 % of the reference + 1 rad/s, for more than 10 ms) as a failure kind.
"""


def add_parser(sub):
    """Add the ``montecarlo`` subcommand and its flags to the ``pmsmjax`` subparsers `sub`."""
    description = (
        "Run N closed-loop runs of a drive's scenario (--motor: a drive file or preset, default book: "
        "1000 r/min step, 10 N m load step at 0.2 s, 0.4 s, 10 kHz, 10 sub-steps; a drive file gives its "
        "own [scenario], control rate, DC link, current limit and bandwidths, derived where absent) with "
        "the plant's R, L_d, L_q, psi_f, J, B and the DC link drawn from their tolerances (default: the "
        "file's [tolerances]; book: R +-20 %, L +-15 %, psi_f +-10 %, J +-50 %, B +-50 %, U_dc +-10 %, "
        "uniform), chunked and sharded over every device. Writes DIR/summary.json (the drive file as "
        "read, percentiles, "
        "failure rates, CVaR, AD sensitivities, Spearman ranks, run and compile time), DIR/histograms.png, "
        "DIR/fan_chart.png, DIR/tornado.png and DIR/chunks/*.npz; running it again resumes (Ctrl-C keeps "
        "every finished chunk). Settings: flags, then --config TOML (below), then built-in defaults."
    )
    p = sub.add_parser(
        "montecarlo",
        help="Monte Carlo robustness study of a drive (drive file or preset) over parameter tolerances",
        description="\n".join(textwrap.wrap(description, 100)),
        epilog=STUDY_TOML,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--n", type=checks.count(), help="number of runs (default 1000)")
    drive_flags.add_motor_flag(p, default=None, default_text="the study TOML's [drive] motor, else book")
    drive_flags.add_override_flags(p)
    checks.add_out_flag(p, "montecarlo_out")
    p.add_argument("--config", default=None, help="study TOML, layout below (default: none)")
    p.add_argument("--seed", type=checks.count(minimum=0), help="sampling seed (default 0)")
    p.add_argument(
        "--chunk-size",
        type=_chunk_size,
        help="most runs per chunk, or 'auto' (default: from the device memory and the drive's bytes per run)",
    )
    p.add_argument("--latin-hypercube", action="store_true", help="Latin hypercube sampling")
    p.add_argument("--clip", action="store_true", help="clip non-physical samples instead of refusing")
    p.add_argument(
        "--sensitivity-runs",
        type=checks.count(minimum=0),
        help="runs differentiated by forward-mode AD (default 256)",
    )
    p.add_argument(
        "--devices",
        type=checks.count(),
        help="CPU only: split the CPU into this many devices, at most its core count (default: every core)",
    )
    add_gains_flag(p)
    p.add_argument(
        "--estimator",
        choices=list(registry.names("estimator", group="observer")),
        help="sensorless study: run on this chapter 5 observer with the I/f start, the plant's R, L, psi_f "
        "drawn against the observer's nominal model (default: the exact sensor)",
    )
    p.add_argument(
        "--distributed",
        action="store_true",
        help="multi-host: call jax.distributed.initialize() first (cluster from SLURM, Open MPI, ... or the "
        "three flags below)",
    )
    p.add_argument(
        "--coordinator",
        metavar="HOST:PORT",
        help="with --distributed: process 0's address (default: from the cluster's environment)",
    )
    p.add_argument(
        "--num-processes",
        type=checks.count(),
        help="with --distributed: number of processes (default: from the cluster's environment)",
    )
    p.add_argument(
        "--process-id",
        type=checks.count(minimum=0),
        help="with --distributed: this process's index, 0 writes the files (default: from the environment)",
    )
    p.add_argument(
        "--compilation-cache",
        metavar="DIR",
        help="keep compiled chunk functions in DIR instead of the persistent cache every command uses "
        "(a later study of the same shape, drive, scenario length, chunk size and devices, skips most of "
        "the compile; default: that cache, see --no-compile-cache)",
    )
    p.add_argument(
        "--linear-stability",
        action="store_true",
        help="also linearise every draw at its final speed and load and count a spectral radius >= 1 as the "
        "failure unstable_linearisation (three-phase FOC on the exact sensor)",
    )
    p.add_argument(
        "--unroll-substeps",
        action="store_true",
        help="write the RK4 sub-steps out instead of looping (faster kernel on a GPU; same results)",
    )
    p.add_argument(
        "--machine",
        choices=("three-phase", "six-phase", "five-phase"),
        help="three-phase drive (default), the six-phase drive (book ch. 7-9) or the five-phase drive "
        "(book ch. 10); --motor then names a six- or five-phase drive file or preset",
    )
    p.add_argument(
        "--control",
        choices=("vsd", "double-dq", "conventional", "pr"),
        help="six- or five-phase control scheme (default vsd; five-phase: vsd, conventional, pr)",
    )
    p.add_argument(
        "--pwm",
        choices=(
            "four-vector",
            "two-vector",
            "decoupled",
            "double-zs",
            "near-four-vector",
            "carrier",
            "sinusoidal",
            "large-vector",
        ),
        help="six-phase modulator (default four-vector); five-phase: near-four-vector (default), carrier, "
        "sinusoidal, large-vector",
    )
    p.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    memory.add_memory_flag(p)
    p.set_defaults(func=run)


def _chunk_size(text: str):
    """``--chunk-size``: ``auto``, or a whole number >= 1 (checked as the other counts are)."""
    return text if text == "auto" else checks.count()(text)


def precheck(args) -> None:
    """Checks that need no model (before JAX starts), the drive file's included."""
    checks.output_folder(args.out)
    if args.config is not None:
        checks.existing_file(args.config, "--config", "study file")
    if args.motor is not None or args.u_dc is not None or args.current_limit is not None:
        from pmsmjax.io.drive_files import drive_spec

        drive = _study_drive_table(args.config)
        machine = args.machine or drive.get("machine", "three-phase")
        drive_spec(
            args.motor or drive.get("motor", "book"),
            n_phases={"six-phase": 6, "five-phase": 5}.get(machine, 3),
            u_dc_v=args.u_dc,
            max_current_a=args.current_limit,
            flags={"u_dc_v": "--u-dc", "max_current_a": "--current-limit"},
        )
    read_gains_flag(args.gains)
    cores = os.cpu_count() or 1
    if args.devices is not None and args.devices > cores:
        raise ParameterError(
            f"--devices {args.devices}: this machine has {cores} CPU core(s); more devices than cores only "
            f"share them (slower, more memory): give at most {cores}, or leave it out (one per core)."
        )
    if args.devices is not None and args.distributed:
        raise ParameterError("--devices splits one machine's CPU; with --distributed leave it out.")
    cluster = [f for f in ("coordinator", "num_processes", "process_id") if getattr(args, f) is not None]
    if cluster and not args.distributed:
        raise ParameterError(f"{checks.flag(cluster[0])} describes a multi-host run: add --distributed.")
    if (
        args.num_processes is not None
        and args.process_id is not None
        and args.process_id >= args.num_processes
    ):
        raise ParameterError(
            f"--process-id {args.process_id}: processes are numbered 0 to {args.num_processes - 1} "
            f"(--num-processes {args.num_processes})."
        )


def _study_drive_table(config) -> dict:
    """The study TOML's ``[drive]`` table (empty without one; its errors are the study reader's)."""
    if config is None:
        return {}
    from pmsmjax.io.toml_parser import read_toml

    try:
        table = read_toml(config, "").get("drive", {})
    except (ParameterError, OSError):
        return {}
    return table if isinstance(table, dict) else {}


def check_memory(study, max_memory_gb: float | None) -> None:
    """Refuse a study whose estimated peak memory
    ([`montecarlo_bytes`][pmsmjax.cli.memory.montecarlo_bytes]) exceeds the budget, before it compiles:
    every run's samples, metrics and decimated record are held until the summary.

    Args:
        study: the [`Study`][tuning.montecarlo.study.Study].
        max_memory_gb: ``--max-memory-gb``, GB, or None.
    """
    import jax

    from tuning.montecarlo.chunking import MAX_RUNS
    from tuning.montecarlo.runner import COLUMNS, OBSERVER_COLUMNS

    n_metrics = len(OBSERVER_COLUMNS if study.estimator else COLUMNS)
    n_record = 2 * (study.n_periods // study.decimate)
    per_device = MAX_RUNS["cpu"] if study.chunk_size == "auto" else study.chunk_size
    chunk = min(study.n, per_device * (jax.local_device_count() if study.chunk_size == "auto" else 1))
    shape = (len(study.parameters), n_metrics, n_record, chunk)
    need = memory.montecarlo_bytes(study.n, *shape)
    budget, _ = memory.budget_bytes(max_memory_gb)
    fit = memory.montecarlo_runs_to_fit(*shape, budget)
    memory.check_fits(
        need,
        f"--n {study.n:,} runs ({len(study.parameters)} parameters, {n_record:,} recorded values per run, "
        f"chunks of {chunk:,})",
        f"give --n {fit:,} or fewer (several studies with different --seed), or a larger --decimate in the "
        "study TOML",
        max_memory_gb,
        floor=memory.BASE_BYTES,
    )


def run(args) -> int:
    """Run the Monte Carlo robustness study of the drive (resuming finished chunks); writes
    summary.json and figures to ``--out``. Returns the exit status."""
    precheck(args)
    # The devices (one per CPU core, or the cluster's hosts) before anything initialises JAX's backends.
    from tuning.montecarlo.cpu_devices import set_up_devices

    set_up_devices(
        args.devices,
        distributed=args.distributed,
        coordinator=args.coordinator,
        num_processes=args.num_processes,
        process_id=args.process_id,
        compilation_cache=args.compilation_cache,
    )
    from tuning.montecarlo import run_study
    from tuning.montecarlo.study import Study
    from tuning.montecarlo.study_file import read_study_toml

    kwargs = read_study_toml(args.config) if args.config else {}
    for key, value in (
        ("n", args.n),
        ("motor", args.motor),
        ("u_dc", args.u_dc),
        ("current_limit", args.current_limit),
        ("seed", args.seed),
        ("chunk_size", args.chunk_size),
        ("sensitivity_runs", args.sensitivity_runs),
        ("sampling", "latin_hypercube" if args.latin_hypercube else None),
        ("nonphysical", "clip" if args.clip else None),
        ("gains", args.gains),
        ("unroll_substeps", True if args.unroll_substeps else None),
        ("machine", args.machine),
        ("control", args.control),
        ("pwm", args.pwm),
        ("estimator", args.estimator),
        ("linear_stability", True if args.linear_stability else None),
    ):
        if value is not None:
            kwargs[key] = value
    study = Study(**kwargs)
    check_memory(study, args.max_memory_gb)
    try:
        s = run_study(study, args.out, progress=not args.no_progress, figures=not args.no_figures)
    except KeyboardInterrupt:
        raise KeyboardInterrupt(
            f"the finished chunks are kept in {args.out}/chunks: rerun the same command to resume"
        ) from None
    if s is None:  # not process 0 of a multi-host run: it only computed its shards
        return 0
    f, m = s["failures"], s["metrics"]
    ch = s["chunks"]
    print(
        f"{s['n_runs']} runs of {s['drive_file']['source']} on {s['devices']['count']} device(s): "
        f"run {s['run_time_s']:.2f} s "
        f"({ch['computed_now']} chunks computed, {ch['loaded']} loaded), compile {s['compile_time_s']:.1f} s"
    )
    for name in ("itae", "overshoot_pct", "settling_time_s", "dip_rpm", "peak_current_a"):
        st = m[name]
        if st["n"]:
            print(f"  {name:16s} p5 {st['p5']:.4g}  p50 {st['p50']:.4g}  p95 {st['p95']:.4g} {st['unit']}")
    for name in ("angle_error_rms_deg", "angle_error_max_deg", "speed_error_rms_rpm"):
        st = m.get(name, {"n": 0})
        if st["n"]:
            print(f"  {name:19s} p50 {st['p50']:.4g}  p95 {st['p95']:.4g}  max {st['max']:.4g} {st['unit']}")
    if "lock_lost" in f:
        print(f"  loss of lock: {f['lock_lost']['count']} runs ({100 * f['lock_lost']['rate']:.2f} %)")
    print(
        f"failures: {100 * f['any']['rate']:.2f} % (current {f['current_limit']['count']}, tracking "
        f"{f['speed_tracking']['count']}, unstable {f['unstable']['count']}); wrote {args.out}/summary.json"
    )
    return 0
