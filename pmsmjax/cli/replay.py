"""``pmsmjax replay``: run the machine under a recorded voltage sequence."""


def add_parser(sub):
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
    p.set_defaults(func=run)


def run(args) -> int:
    from ..replay import replay_file

    path = replay_file(args.log, args.motor, args.out, hold=args.hold, n_substeps=args.substeps)
    print(f"wrote {path}")
    return 0
