"""``pmsmjax montecarlo``: a Monte Carlo robustness study of the book drive (:mod:`tuning.montecarlo`)."""


def add_parser(sub):
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
    p.set_defaults(func=run)


def run(args) -> int:
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
