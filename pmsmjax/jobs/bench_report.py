"""The plain-text table of ``pmsmjax bench``'s figures ([`pmsmjax.jobs.bench.run`][pmsmjax.jobs.bench.run]):
the single run, the batch, the batch gradient and the forward- against reverse-mode tables with their
crossovers. Plain Python: the figures are a dict.
"""

__all__ = ["format_table", "row"]


def row(label: str, value: str, note: str = "") -> str:
    """One line of the plain-text tables: label, right-aligned value, note."""
    return f"{label:<46}{value:>14}  {note}".rstrip()


def format_table(r: dict) -> str:
    """A readable plain-text table of the figures returned by `run`."""
    m = r["machine"]
    quick = "  [QUICK: sizes shrunk, timings not meaningful]" if r["quick"] else ""
    n_batch_loss = r["grad_batch_size"] * r["n_periods"] / r["forward_batch64_s"]
    lines = [
        f"pmsmjax core benchmark ({r['dtype']}, book drive: {r['n_periods']} periods of "
        f"{1e6 * r['drive']['Ts_s']:.0f} us, {r['drive']['n_substeps']} RK4 sub-steps each){quick}",
        f"machine: {m['cpu']}, {m['cpu_count']} cores, jax {m['jax']}, {m['backend']} ({m['device']})",
        "",
        row(
            "single run (simulate)",
            f"{r['library_ms']:.2f} ms",
            f"{r['periods_per_s_single']:,.0f} periods/s",
        ),
        row("  compile time", f"{r['compile_time_s']:.2f} s"),
        row(
            f"vmap batch of {r['batch_size']}, full traces",
            f"{r['batch_run_s']:.3f} s",
            f"{r['periods_per_s_batch256']:,.0f} periods/s",
        ),
        row("  compile time", f"{r['batch_compile_time_s']:.2f} s"),
        row(
            f"batch-{r['grad_batch_size']} mean ITAE, forward pass",
            f"{r['forward_batch64_s']:.3f} s",
            f"{n_batch_loss:,.0f} periods/s",
        ),
        row(
            "  reverse gradient w.r.t. 7 gains",
            f"{r['grad_batch64_s']:.3f} s",
            f"gradient / forward = {r['grad_over_forward_ratio']:.2f}",
        ),
        row("  gradient compile time", f"{r['grad_compile_time_s']:.2f} s"),
    ]
    for sub in r["grad_over_forward_by_substeps"]:
        lines.append(
            row(
                f"  same with {sub['n_substeps']} sub-step(s) per period",
                f"{sub['grad_s']:.3f} s",
                f"gradient / forward = {sub['ratio']:.2f}",
            )
        )
    lines += _mode_table(
        "single-scenario ITAE gradient", r["forward_vs_reverse"], r["mode_crossover_n_params"]
    )
    if r["forward_vs_reverse_batch64"]:
        title = f"batch-{r['grad_batch_size']} mean ITAE gradient w.r.t. controller gains"
        lines += _mode_table(title, r["forward_vs_reverse_batch64"], r["mode_crossover_n_params_batch64"])
    return "\n".join(lines)


def _mode_table(title: str, rows: list[dict], n: int) -> list[str]:
    """Lines of a forward- vs reverse-mode table (times in s) ending with its crossover ``n``
    ([`pmsmjax.jobs.bench.mode_crossover`][pmsmjax.jobs.bench.mode_crossover] of ``rows``)."""
    lines = [
        "",
        f"{title}: best times and compile times, s",
        "".join(f"{h:>10}" for h in ("n params", "forward", "reverse", "fwd/rev", "|dg|/|g|"))
        + f"{'comp fwd':>10}{'comp rev':>10}",
    ]
    for r in rows:
        lines.append(
            f"{r['n_params']:>10}{r['forward_s']:>10.4f}{r['reverse_s']:>10.4f}"
            f"{r['forward_s'] / r['reverse_s']:>10.2f}{r['grad_rel_diff']:>10.1e}"
            f"{r['forward_compile_s']:>10.2f}{r['reverse_compile_s']:>10.2f}"
        )
    if n < max(r["n_params"] for r in rows):
        lines.append(f"  forward mode is faster up to n = {n} parameters")
    else:
        lines.append(f"  forward mode is faster at every measured n (<= {n}): the crossover lies above")
    return lines
