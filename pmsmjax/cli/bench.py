"""``pmsmjax bench``: the speed benchmark of :mod:`benchmarks.bench_core`."""

from pmsmjax.cli import checks


def add_parser(sub):
    p = sub.add_parser(
        "bench",
        help="measure simulation speed, compile and gradient time (benchmarks/bench_core.py)",
        description="Speed of the book drive simulation against a minimal hand-written loop, same run.",
    )
    p.add_argument("--json", default=None, help="write the results to this JSON file (default: none)")
    p.add_argument("--quick", action="store_true", help="small sizes (a smoke run)")
    p.set_defaults(func=run)


def run(args) -> int:
    if args.json is not None:
        checks.output_file(args.json, "--json")
    from benchmarks.bench_core import main as bench_main

    bench_main(args.json, quick=args.quick)
    return 0
