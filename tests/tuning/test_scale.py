"""Scale: the chunk-size rule, the balanced chunk layout, the pipelined chunk loop, the
Spearman ranks from one sort per column, the tuner's ahead-of-time compiled and pipelined loop, and the
scale benchmark's report. Compared with scipy, XLA's own memory analysis, brute force and the
one-call-at-a-time paths; short scenarios and a handful of runs keep it quick."""

import dataclasses
import math
from types import SimpleNamespace

import equinox as eqx
import jax
import numpy as np
import optax
import pytest
from scipy.stats import rankdata, spearmanr

from pmsmjax.presets.three_phase import book_drive
from pmsmjax.spec.validation import ParameterError
from tuning.autotune import TuneConfig, tune
from tuning.autotune.objectives import ObjectiveWeights
from tuning.autotune.scenario_batches import make_batch
from tuning.autotune.tuner import _value_and_grad, compile_value_and_grad
from tuning.montecarlo import StudyRunner, chunk_layout, load_results, run_study
from tuning.montecarlo import study as mc_study
from tuning.montecarlo.chunking import (
    MAX_RUNS,
    MEMORY_FRACTION,
    MIN_RUN_PERIODS,
    THROUGHPUT_CAP,
    auto_chunk_size,
    device_free_bytes,
    host_available_bytes,
)
from tuning.montecarlo.distributions import sample
from tuning.montecarlo.kernel import METRICS
from tuning.montecarlo.study import Study
from tuning.montecarlo.summary import average_ranks, spearman_ranks

# 0.02 s (200 periods) of the book drive: speed step to 600 r/min, 3 N m load at 0.01 s.
SHORT = dict(duration_s=0.02, load_time_s=0.01, speed_rpm=600.0, load_nm=3.0, decimate=20)

# ------------------------------------------------------------------------------------- the chunk rule


def test_chunk_rule_takes_the_smallest_of_memory_throughput_and_runs():
    mib = 2**20
    # 64 MiB free, 0.5 MiB per run: half of it holds 64 runs per device, below the CPU cap.
    size, how = auto_chunk_size(10**6, 2, mib // 2, free_bytes=64 * mib, platform="cpu")
    assert size == 2 * int(MEMORY_FRACTION * 64 * mib) // (mib // 2) == 128
    assert how["limited_by"] == "memory" and how["rule"] == "auto"
    # Plenty of memory: the platform's throughput cap per device.
    size, how = auto_chunk_size(10**7, 4, 1000, free_bytes=80 * 2**30, platform="gpu")
    assert size == 4 * THROUGHPUT_CAP["gpu"] and how["limited_by"] == "throughput"
    size, _ = auto_chunk_size(10**7, 2, 1000, free_bytes=80 * 2**30, platform="cpu")
    assert size == 2 * THROUGHPUT_CAP["cpu"]
    # Short runs on a CPU: at least 2^18 run-periods per device, at most 16,384 runs; long runs keep the cap.
    size, _ = auto_chunk_size(10**7, 2, 1000, n_periods=20, free_bytes=80 * 2**30, platform="cpu")
    assert size == 2 * math.ceil(MIN_RUN_PERIODS["cpu"] / 20) == 26_216
    size, _ = auto_chunk_size(10**7, 2, 1000, n_periods=1, free_bytes=80 * 2**30, platform="cpu")
    assert size == 2 * MAX_RUNS["cpu"]
    size, _ = auto_chunk_size(10**7, 2, 1000, n_periods=4000, free_bytes=80 * 2**30, platform="cpu")
    assert size == 2 * THROUGHPUT_CAP["cpu"]
    size, _ = auto_chunk_size(10**7, 1, 1000, n_periods=20, free_bytes=80 * 2**30, platform="gpu")
    assert size == THROUGHPUT_CAP["gpu"]
    # A small study: all of it in one chunk.
    size, how = auto_chunk_size(300, 2, 1000, free_bytes=80 * 2**30, platform="cpu")
    assert size == 300 and how["limited_by"] == "runs"
    # Not even one run fits: still two per device (the smallest chunk that is bitwise device-invariant).
    size, _ = auto_chunk_size(10**6, 3, 10**9, free_bytes=mib, platform="gpu")
    assert size == 6


def test_free_memory_from_device_statistics_or_host_ram():
    gpu = lambda limit, used: SimpleNamespace(
        memory_stats=lambda: {"bytes_limit": limit, "bytes_in_use": used}
    )
    assert device_free_bytes([gpu(100, 30), gpu(100, 50)]) == 50  # the fullest device decides
    cpu = SimpleNamespace(memory_stats=lambda: None)
    available = host_available_bytes()
    with open("/proc/meminfo") as f:
        total = next(int(line.split()[1]) * 1024 for line in f if line.startswith("MemTotal:"))
    assert 0 < available <= total
    assert abs(device_free_bytes([cpu, cpu]) - available // 2) < 0.05 * total  # shared by the CPU devices


@pytest.mark.slow
@pytest.mark.parametrize("vary_speed", [False, True])
def test_bytes_per_run_bounds_xla_memory_analysis(vary_speed):
    # XLA's memory analysis of the compiled chunk function at two batch sizes: its growth per run is
    # what a run costs. The estimate must not be below it (a chunk would not fit), nor far above it
    # (chunks would be needlessly small): within 5x, as the chunking docstring states for the book study.
    params = {"motor.R": {"tolerance": 0.2}, "motor.J": {"tolerance": 0.3}}
    if vary_speed:
        params["scenario.speed_rpm"] = {"tolerance": 0.2}
    runner = StudyRunner(Study(n=8, sensitivity_runs=0, parameters=params, **SHORT))

    def total(rows):
        m = runner.compile("forward", rows).memory_analysis()
        return m.temp_size_in_bytes + m.output_size_in_bytes + m.argument_size_in_bytes

    per_run = (total(64) - total(16)) / 48
    estimate = runner.per_run_bytes()
    assert per_run <= estimate <= 5 * per_run, (per_run, estimate)
    # The output shapes it counts are the kernel's own.
    traced = jax.eval_shape(runner._packed, jax.ShapeDtypeStruct((len(runner.names),), runner.dtype))
    assert jax.tree.structure(traced) == jax.tree.structure(runner.output_shapes())
    for a, b in zip(jax.tree.leaves(traced), jax.tree.leaves(runner.output_shapes()), strict=True):
        assert (a.shape, a.dtype) == (b.shape, b.dtype)


# ------------------------------------------------------------------------------------- chunk layout


def test_chunk_layout_is_balanced_and_minimal():
    assert chunk_layout(10_000, 2048, 2) == (2000, 5)  # not 4 x 2048 and a fifth padded by 240 runs
    for n in (1, 2, 3, 7, 10, 33, 100, 1000, 4097):
        for chunk in (1, 2, 3, 4, 6, 64, 2048):
            for devices in (1, 2, 3, 4):
                size, count = chunk_layout(n, chunk, devices)
                unit = 2 * devices
                largest = math.ceil(min(chunk, n) / unit) * unit
                assert size % unit == 0 and unit <= size <= largest
                assert count == math.ceil(n / largest)  # as few chunks as the largest size needs
                assert (count - 1) * size < n <= count * size  # no empty chunk, every run in one
                assert count * size - n < count * unit  # padding below one unit per chunk


# ----------------------------------------------------------------------------- pipelined chunk loop

STUDY = Study(n=10, chunk_size=4, sensitivity_runs=0, seed=2, **SHORT)


@pytest.fixture(scope="module")
def study_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("study")
    return out, run_study(STUDY, out, progress=False, figures=False)


def test_every_chunk_lands_in_its_rows(study_dir):
    # The pipelined loop (chunk c + 1 dispatched before chunk c is fetched and written) against one
    # forward call over all runs at once.
    out, summary = study_dir
    assert summary["chunks"]["count"] == 3 and summary["chunk_rule"] == {"rule": "given"}
    runner = StudyRunner(STUDY)
    dists = mc_study.distributions(STUDY, runner.drive)
    samples = sample(dists, STUDY.n, STUDY.seed, STUDY.sampling)
    values = np.stack([samples[k] for k in runner.names], axis=1)
    metrics, record = runner.forward(values)
    stored = load_results(out)
    for k in (*METRICS, "finite"):
        np.testing.assert_array_equal(stored[k], metrics[k], err_msg=k)
    for k in ("speed_rpm", "i_q_a"):
        np.testing.assert_array_equal(stored[k], record[k], err_msg=k)
    assert summary["metrics"]["itae"]["p50"] == pytest.approx(np.percentile(metrics["itae"], 50), rel=1e-12)


def test_a_missing_middle_chunk_is_recomputed_between_loaded_ones(study_dir, tmp_path):
    out, reference = study_dir
    for p in (out / "chunks").glob("chunk_*.npz"):
        (tmp_path / "chunks").mkdir(exist_ok=True)
        (tmp_path / "chunks" / p.name).write_bytes(p.read_bytes())
    (tmp_path / "chunks" / "chunk_00001.npz").unlink()
    seen = []
    again = run_study(STUDY, tmp_path, progress=False, figures=False, after_chunk=seen.append)
    assert seen == [0, 1, 2]  # reported in order, each after its file exists
    assert again["chunks"]["computed_now"] == 1 and again["chunks"]["loaded"] == 2
    assert again["metrics"] == reference["metrics"] and again["spearman"] == reference["spearman"]


@pytest.mark.slow
def test_two_processes_give_the_same_summary(study_dir, tmp_path):
    # jax.distributed on one machine: two processes with one CPU device each (the multi-host path:
    # samples drawn by both, shards fed by each, results gathered, files written by process 0, the
    # automatic chunk size agreed on), against the one-process study above.
    import json
    import os
    import socket
    import subprocess
    import sys
    from pathlib import Path

    from tuning.montecarlo import VOLATILE_KEYS

    with socket.socket() as sock:
        sock.bind(("localhost", 0))
        port = sock.getsockname()[1]
    root = Path(__file__).resolve().parents[2]
    study = {**vars(STUDY), "chunk_size": "auto"}
    code = (
        "import jax, json, sys; jax.config.update('jax_enable_x64', True)\n"
        f"jax.distributed.initialize('localhost:{port}', num_processes=2, process_id=int(sys.argv[1]))\n"
        "from tuning.montecarlo import run_study; from tuning.montecarlo.study import Study\n"
        f"s = run_study(Study(**{study!r}), sys.argv[2], progress=False, figures=False)\n"
        "print(json.dumps(s))\n"
    )
    env = {**os.environ, "XLA_FLAGS": "--xla_force_host_platform_device_count=1", "PYTHONPATH": str(root)}
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", code, str(i), str(tmp_path)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
            cwd=root,
        )
        for i in (0, 1)
    ]
    outputs = [p.communicate(timeout=600) for p in procs]
    for p, (_, err) in zip(procs, outputs, strict=True):
        assert p.returncode == 0, err[-2000:]
    two = json.loads(outputs[0][0].strip().splitlines()[-1])
    assert outputs[1][0].strip().splitlines()[-1] == "null"  # process 1 computes, process 0 reports
    assert two["devices"] == {"count": 2, "kind": "cpu", "processes": 2}
    assert two["chunk_rule"]["limited_by"] == "runs" and two["chunk_rule"]["free_bytes_per_device"] > 2**20
    _, reference = study_dir
    strip = lambda s: {k: v for k, v in s.items() if k not in (*VOLATILE_KEYS, "study")}
    assert strip(two) == strip(reference)


def test_auto_chunk_size_is_recorded_and_refusals_name_the_field(tmp_path):
    s = run_study(Study(**{**vars(STUDY), "chunk_size": "auto"}), tmp_path, progress=False, figures=False)
    rule = s["chunk_rule"]
    assert rule["rule"] == "auto" and rule["limited_by"] == "runs"  # 10 runs: one chunk
    assert s["chunks"]["count"] == 1 and rule["per_run_bytes"] > 0 and rule["free_bytes_per_device"] > 0
    with pytest.raises(ParameterError, match='chunk_size must be an int >= 1 or "auto"'):
        Study(chunk_size="big")
    from pmsmjax.cli import main

    with pytest.raises(SystemExit) as exit_info:
        main(["montecarlo", "--chunk-size", "big", "--out", str(tmp_path / "x")])
    assert exit_info.value.code == 2
    out = ["--out", str(tmp_path / "x")]
    assert main(["montecarlo", "--process-id", "1", *out]) == 2  # cluster flags need --distributed
    assert main(["montecarlo", "--distributed", "--num-processes", "2", "--process-id", "2", *out]) == 2


def test_compilation_cache_flag_keeps_the_compiled_chunk_function(tmp_path):
    # In a child process: the flag sets JAX's cache directory for the whole process.
    import json
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    config = tmp_path / "study.toml"
    config.write_text(
        "[study]\nsensitivity_runs = 0\ndecimate = 20\n[scenario]\nduration_s = 0.02\nload_time_s = 0.01\n"
        '[parameters."motor.R"]\ntolerance = 0.2\n'
    )
    cache, out = tmp_path / "cache", tmp_path / "mc"
    args = ["montecarlo", "--n", "4", "--out", str(out), "--config", str(config), "--no-figures"]
    args += ["--no-progress", "--compilation-cache", str(cache)]
    code = f"import sys; from pmsmjax.cli import main; sys.exit(main({args!r}))"
    env = {**os.environ, "PYTHONPATH": str(root)}
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=root)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert any(cache.iterdir())  # the chunk function's executable, kept for the next run
    assert json.loads((out / "summary.json").read_text())["n_runs"] == 4


# -------------------------------------------------------------------------------------- Spearman ranks


def test_average_ranks_and_spearman_match_scipy():
    rng = np.random.default_rng(1)
    x = rng.integers(0, 30, 500).astype(float)  # many ties
    np.testing.assert_array_equal(average_ranks(x), rankdata(x))
    y = rng.random(500)
    np.testing.assert_array_equal(average_ranks(y), rankdata(y))
    n = 400
    samples = {"a": rng.random(n), "b": rng.integers(0, 5, n).astype(float), "c": np.full(n, 2.0)}
    m = {k: rng.random(n) + samples["a"] * i for i, k in enumerate(METRICS)}
    m["settling_time_s"] = np.round(m["settling_time_s"] * 4)  # ties in a metric too
    m["overshoot_pct"][:7] = np.nan  # non-finite in one metric only: its own set of runs
    m["finite"] = np.ones(n)
    m["finite"][-3:] = 0.0
    got = spearman_ranks(samples, m)
    for metric in METRICS:
        ok = (m["finite"] > 0.5) & np.isfinite(m[metric])
        for p in ("a", "b"):
            expected = spearmanr(samples[p][ok], m[metric][ok]).statistic
            assert got[metric][p] == pytest.approx(expected, abs=1e-12), (metric, p)
        assert got[metric]["c"] is None  # a constant parameter has no rank correlation


# ---------------------------------------------------------------------------------------------- tuner


@pytest.fixture(scope="module")
def tuning_problem():
    drive = book_drive(n_substeps=1)
    batch = make_batch(4, seed=3, duration_s=(0.02, 0.03))
    return drive, batch


@pytest.mark.slow
def test_pipelined_tuner_follows_the_one_at_a_time_path(tuning_problem):
    # Adam written out from its definition with the tuner's cost function called through eqx.filter_jit
    # (one call after another, every result waited for), against tune(): same costs, same gains.
    drive, batch = tuning_problem
    weights = ObjectiveWeights()
    config = TuneConfig(method="adam", max_iterations=4, patience=100)
    result = tune(drive, batch, weights, config, progress=False)
    from tuning.parameters import LogParameterisation

    param = LogParameterisation(drive, config.names, config.bounds)
    optimiser = optax.adam(
        optax.cosine_decay_schedule(config.learning_rate, config.max_iterations, alpha=0.1)
    )

    @eqx.filter_jit
    def step(theta, grad, state):
        updates, state = optimiser.update(grad, state, theta)
        return param.project(optax.apply_updates(theta, updates)), state

    theta = param.initial_theta()
    state = optimiser.init(theta)
    history = []
    for _ in range(config.max_iterations):
        cost, _, grad = _value_and_grad(theta, drive, batch, weights, param)
        history.append(float(cost))
        theta, state = step(theta, grad, state)
    assert result.history == history
    assert result.iterations == 4 and 0.0 <= result.waiting_time_s <= result.wall_time_s
    assert result.compile_time_s > 0


@pytest.mark.slow
def test_ahead_of_time_evaluation_equals_the_jit_one(tuning_problem):
    drive, batch = tuning_problem
    weights = dataclasses.replace(ObjectiveWeights(), overshoot_smoothing_pct=1.0, current_smoothing_a=0.1)
    from tuning.parameters import LogParameterisation

    param = LogParameterisation(drive, ("speed", "current"))
    theta = param.initial_theta() + 0.1
    evaluate = compile_value_and_grad(theta, drive, batch, weights, param)
    for a, b in zip(evaluate(theta), _value_and_grad(theta, drive, batch, weights, param), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


# ------------------------------------------------------------------------------------- unrolled sub-steps


def test_unrolled_substeps_are_the_same_equations_in_one_program():
    import re

    import pmsmjax
    from pmsmjax.inverters.averaged import AveragedBridge
    from pmsmjax.simulate import period_inputs

    drive = book_drive()
    unrolled = mc_study.build_drive(Study(unroll_substeps=True))
    assert unrolled.bridge.unroll_substeps and not drive.bridge.unroll_substeps
    assert isinstance(unrolled.bridge, AveragedBridge)
    assert float(unrolled.bridge.u_dc) == float(drive.bridge.u_dc)
    servo = mc_study.build_drive(Study(motor="servo-400w", unroll_substeps=True))
    assert float(servo.bridge.voltage_error.dead_time) == 5e-7  # the file's dead time survives unrolling
    scenario = pmsmjax.presets.book_scenario(600.0, 3.0, load_time_s=0.01, duration_s=0.02)
    x = jax.tree.map(lambda a: a[0], period_inputs(scenario, drive.Ts))
    for d, expected in ((drive, {"unroll=1"}), (unrolled, {"unroll=10"})):  # the 10 RK4 sub-steps
        jaxpr = str(jax.make_jaxpr(lambda s, d=d: d.step(s, x))(d.init()))
        assert set(re.findall(r"unroll=\w+", jaxpr)) == expected
    a, b = pmsmjax.simulate(drive, scenario), pmsmjax.simulate(unrolled, scenario)
    for name in ("omega_m", "i_dq", "theta_e", "u_dq_ref"):
        np.testing.assert_allclose(getattr(b, name), getattr(a, name), rtol=1e-13, atol=1e-12, err_msg=name)
    with pytest.raises(ParameterError, match="unroll_substeps"):
        Study(unroll_substeps="yes")


# ------------------------------------------------------------------------------------------- benchmark


@pytest.mark.slow
def test_scale_benchmark_reports_every_row():
    from benchmarks.bench_scale import ROW_KEYS, format_table, run

    r = run(quick=True)
    assert [row["workload"] for row in r["rows"]] == ["montecarlo book", "montecarlo short", "tune iteration"]
    for row in r["rows"]:
        assert all(k in row for k in ROW_KEYS), row
        assert row["kernel_s"] > 0 and row["whole_s"] > 0
        assert row["runs_per_s"] == pytest.approx(
            row["n"] / (row["kernel_s"] if "chunk_size" in row else row["whole_s"])
        )
        assert row["periods_per_s"] == pytest.approx(row["runs_per_s"] * row["periods_per_run"])
    assert jax.devices()[0].device_kind in format_table(r)
