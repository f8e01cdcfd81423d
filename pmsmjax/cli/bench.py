"""``pmsmjax bench``: how fast the simulator runs on this machine
([`pmsmjax.jobs.bench`][pmsmjax.jobs.bench]).

The comparison with a hand-written loop is a benchmark of the repository, not of an installation:
``python -m benchmarks.bench_core``.
"""

from pmsmjax.cli import checks


def add_parser(sub):
    """Add the ``bench`` subcommand and its flags to the ``pmsmjax`` subparsers `sub`."""
    p = sub.add_parser(
        "bench",
        help="measure simulation speed, compile and gradient time on this machine",
        description="Speed of the book drive simulation on this machine: compile time, one run, a vmapped "
        "batch, the gradient of a batch loss, forward- against reverse-mode gradients.",
    )
    p.add_argument("--json", default=None, help="write the results to this JSON file (default: none)")
    p.add_argument("--quick", action="store_true", help="small sizes (a smoke run)")
    p.set_defaults(func=run)


def run(args) -> int:
    """Measure compile, run and gradient times of the book drive on this machine; exit status."""
    if args.json is not None:
        checks.output_file(args.json, "--json")
    import json

    from pmsmjax.io.logs import atomic_write
    from pmsmjax.jobs.bench import bench

    result = bench(quick=args.quick)
    print(result.table)
    if args.json is not None:
        text = json.dumps(result.figures, indent=2) + "\n"
        atomic_write(args.json, lambda f: f.write(text.encode()))
        print(f"wrote {args.json}")
    return 0
