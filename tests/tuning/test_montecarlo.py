"""Monte Carlo studies: the kernel's metrics against full traces, sampling, summaries against independent
computations, chunked = unchunked, 1 device = 4 devices, interrupted + resumed = uninterrupted, AD
sensitivities against finite differences, bad input. Short scenarios and few runs keep it quick."""

import copy
import json
import os
import subprocess
import sys
from pathlib import Path

import equinox as eqx
import numpy as np
import pytest
from helpers.gradient_check import CentralDifferences, assert_gradient_close

import pmsmjax
from pmsmjax.analysis import metrics
from pmsmjax.machines.motor import PMSMParameters
from pmsmjax.presets.three_phase import book_drive
from pmsmjax.spec.validation import ParameterError
from pmsmjax.units import rad_s_to_rpm
from tuning.montecarlo import VOLATILE_KEYS, StudyRunner, chunk_layout, physical_range, run_study
from tuning.montecarlo import study as mc_study
from tuning.montecarlo.distributions import Distribution, sample, unit_samples
from tuning.montecarlo.kernel import METRICS, run_metrics
from tuning.montecarlo.study import Study
from tuning.montecarlo.study_file import read_study_toml
from tuning.montecarlo.summary import cvar, failures, metric_statistics, spearman_ranks

ROOT = Path(__file__).resolve().parents[2]
# 0.06 s (600 periods): speed step to 600 r/min, 3 N m load at 0.03 s.
SHORT = dict(duration_s=0.06, load_time_s=0.03, speed_rpm=600.0, load_nm=3.0, decimate=20)


def results_of(summary: dict) -> dict:
    """The summary without how (fast) it ran: a deep copy, safe to edit."""
    return copy.deepcopy({k: v for k, v in summary.items() if k not in VOLATILE_KEYS})


# ------------------------------------------------------------------------------------------ the kernel


@pytest.mark.slow
def test_online_metrics_equal_metrics_of_the_full_trace():
    # A light plant and a weakly damped speed loop, so that the speed overshoots and settles before the load.
    drive = book_drive(PMSMParameters(1.1, 5e-3, 5.5e-3, 0.17, 0.0015, 0.01))
    drive = eqx.tree_at(
        lambda d: d.controller.speed.active_damping, drive, drive.controller.speed.active_damping * 0.1
    )
    scenario = pmsmjax.presets.book_scenario(800.0, 6.0, load_time_s=0.1, duration_s=0.2)
    m, rec = run_metrics(drive, scenario, 0.1, decimate=40)
    tr = pmsmjax.simulate(drive, scenario)
    t, w, ref = np.asarray(tr.t), np.asarray(tr.omega_m), np.asarray(tr.speed_ref)
    pre = t < 0.1
    ws = w[pre]
    assert float(m["itae"]) == pytest.approx(float(metrics.itae(t, ref - w)), rel=1e-12)
    assert float(m["overshoot_pct"]) == pytest.approx(float(metrics.overshoot(ws, 0.0, ref[0])), rel=1e-12)
    assert float(m["overshoot_pct"]) > 0.1  # the check means something
    settling = float(metrics.settling_time(t[pre], ws, 0.0, ref[0], 0.02))
    assert np.isfinite(settling) and float(m["settling_time_s"]) == pytest.approx(settling, abs=1e-12)
    dip, _ = metrics.disturbance_dip(t, w, 0.1, ref[0], 1.0)
    assert float(m["dip_rpm"]) == pytest.approx(float(rad_s_to_rpm(dip)), rel=1e-12)
    peak = float(metrics.peak_phase_current(np.asarray(tr.i_abc)))
    assert float(m["peak_current_a"]) == pytest.approx(peak, rel=1e-12)
    final = float(rad_s_to_rpm(metrics.steady_state_error(w, ref, 200)))
    assert float(m["final_error_rpm"]) == pytest.approx(final, rel=1e-9, abs=1e-12)
    assert float(m["finite"]) == 1.0
    np.testing.assert_allclose(np.asarray(rec["speed_rpm"]), rad_s_to_rpm(w[::40]), rtol=1e-14)
    np.testing.assert_array_equal(np.asarray(rec["i_q_a"]), np.asarray(tr.i_dq)[::40, 1])


# ---------------------------------------------------------------------------------------- distributions


def test_distributions_have_their_stated_spread():
    d = {
        "u": Distribution("uniform", 2.0, 0.2),
        "n": Distribution("normal", 2.0, 0.3, sigmas=3.0),
        "l": Distribution("lognormal", 2.0, 0.5, sigmas=2.0),
    }
    s = sample(d, 40_000, seed=3)
    assert 1.6 <= s["u"].min() and s["u"].max() <= 2.4
    assert np.mean(s["u"]) == pytest.approx(2.0, abs=4 * 0.4 / np.sqrt(12 * 40_000))
    assert np.std(s["n"]) == pytest.approx(2.0 * 0.1, rel=0.02)  # band = 3 sigma
    assert np.median(s["l"]) == pytest.approx(2.0, rel=0.01)
    assert np.std(np.log(s["l"] / 2.0)) == pytest.approx(np.log(1.5) / 2.0, rel=0.02)
    again = sample(d, 40_000, seed=3)
    assert all(np.array_equal(s[k], again[k]) for k in d)  # seeded
    assert not np.array_equal(s["u"], sample(d, 40_000, seed=4)["u"])


def test_latin_hypercube_puts_one_sample_in_every_stratum():
    u = unit_samples(50, 3, seed=1, sampling="latin_hypercube")
    for j in range(3):
        assert sorted(np.floor(u[:, j] * 50).astype(int)) == list(range(50))


@pytest.mark.parametrize("tolerance", [-0.1, float("nan")])
def test_negative_or_nan_tolerance_is_refused(tolerance):
    with pytest.raises(ParameterError, match="tolerance"):
        sample({"motor.R": Distribution("uniform", 1.0, tolerance)}, 10, seed=0)
    with pytest.raises(ParameterError, match="tolerance"):
        run_study(Study(n=4, parameters={"motor.R": {"tolerance": tolerance}}, **SHORT), "unused")


def test_nonphysical_samples_are_counted_and_refused_or_clipped(tmp_path):
    nominals = {"motor.J": 0.003, "motor.B": 0.008}
    raw = sample({k: Distribution("normal", v, 1.0, sigmas=1.0) for k, v in nominals.items()}, 1000, seed=0)
    expected = {"motor.J": int(np.sum(raw["motor.J"] <= 0)), "motor.B": int(np.sum(raw["motor.B"] < 0))}
    assert expected["motor.J"] > 100  # a one-sigma band of 100 %: about 16 % below zero
    with pytest.raises(ParameterError, match=f"motor.J: {expected['motor.J']}"):
        physical_range.enforce_physical({k: v.copy() for k, v in raw.items()}, nominals, "refuse")
    clipped = {k: v.copy() for k, v in raw.items()}
    counts = physical_range.enforce_physical(clipped, nominals, "clip")
    assert counts == expected
    assert clipped["motor.J"].min() == pytest.approx(0.01 * 0.003) and clipped["motor.B"].min() == 0.0


def test_bad_study_input_names_the_field():
    for kwargs, match in (
        ({"n": 0}, "n must be"),
        ({"load_time_s": 0.5}, "load_time_s"),
        ({"parameters": {"motor.X": {"tolerance": 0.1}}}, "unknown study parameter"),
        ({"parameters": {"motor.R": {"distribution": "cauchy", "tolerance": 0.1}}}, "cauchy"),
        ({"sampling": "sobol"}, "sampling"),
        ({"nonphysical": "ignore"}, "nonphysical"),
        # Inductances down to 0.1 % of nominal: R/L too fast for 10 RK4 sub-steps, caught before compiling.
        ({"parameters": {"motor.L_d": {"tolerance": 0.999}}}, "n_substeps >= "),
    ):
        with pytest.raises(ParameterError, match=match):
            run_study(Study(**kwargs), "unused")


def test_study_toml(tmp_path):
    path = tmp_path / "study.toml"
    path.write_text(
        '[study]\nn = 7\nsampling = "latin_hypercube"\n[scenario]\nspeed_rpm = 500.0\n'
        '[thresholds]\ncurrent_a = 20.0\n[parameters."motor.R"]\ndistribution = "normal"\ntolerance = 0.3\n'
    )
    study = Study(**read_study_toml(path))
    assert (study.n, study.sampling, study.speed_rpm, study.current_threshold) == (
        7,
        "latin_hypercube",
        500.0,
        20.0,
    )
    assert study.parameters == {"motor.R": {"distribution": "normal", "tolerance": 0.3}}
    path.write_text("[study]\nruns = 7\n")
    with pytest.raises(ParameterError, match="runs"):
        read_study_toml(path)


# ------------------------------------------------------------------------------------------- summaries


def test_statistics_against_a_hand_computation():
    rng = np.random.default_rng(0)
    x = rng.normal(size=101)
    stats = metric_statistics(np.concatenate([x, [np.nan]]), alpha=0.9)
    s = np.sort(x)  # 101 values: the p-th percentile (linear) sits at index p
    for p in (1, 5, 25, 50, 75, 95, 99):
        assert stats[f"p{p}"] == pytest.approx(s[p])
    assert stats["n"] == 101
    assert stats["cvar90"] == pytest.approx(np.mean(s[-11:]))  # ceil(0.1 * 101) = 11 worst
    assert cvar(np.arange(10.0), 0.95) == 9.0


def test_failure_counts_and_spearman_ranks():
    m = {k: np.zeros(6) for k in METRICS}
    m["finite"] = np.array([1, 1, 1, 1, 0, 1.0])
    m["peak_current_a"] = np.array([10, 16, 15.7, 10, np.nan, 10.0])
    m["final_error_rpm"] = np.array([0, 0, -12, 3, np.nan, 11.0])
    f = failures(m, 15.75, 10.0)
    assert f["current_limit"]["count"] == 2  # run 1, and the diverged run 4
    assert f["speed_tracking"]["count"] == 3  # runs 2, 5 and 4
    assert f["unstable"]["count"] == 1 and f["any"]["count"] == 4
    x = np.array([3.0, 1.0, 2.0, 5.0, 4.0, 0.0])
    m["itae"] = x**3  # monotonic in x: rho = 1 over the finite runs
    m["dip_rpm"] = -x
    ranks = spearman_ranks({"motor.R": x}, m)
    assert ranks["itae"]["motor.R"] == pytest.approx(1.0) and ranks["dip_rpm"]["motor.R"] == pytest.approx(
        -1.0
    )
    assert ranks["overshoot_pct"]["motor.R"] is None  # constant metric


# ----------------------------------------------------------------------- execution: chunks and devices

STUDY = Study(n=10, chunk_size=4, sensitivity_runs=0, seed=5, **SHORT)


@pytest.fixture(scope="module")
def chunked(tmp_path_factory):
    out = tmp_path_factory.mktemp("chunked")
    return out, run_study(STUDY, out, progress=False, figures=False)


def test_chunk_layout_pads_to_the_devices():
    assert chunk_layout(10, 4, 1) == (4, 3)
    assert chunk_layout(10, 6, 4) == (8, 2)  # 6 rounded up to two runs on each of 4 devices
    assert chunk_layout(3, 1024, 4) == (8, 1)
    assert chunk_layout(5, 3, 1) == (4, 2)


@pytest.mark.slow
def test_chunked_equals_unchunked(chunked, tmp_path):
    _, summary = chunked
    assert summary["chunks"] == {"size": 4, "count": 3, "computed_now": 3, "loaded": 0}
    whole = run_study(Study(**{**vars(STUDY), "chunk_size": 16}), tmp_path, progress=False, figures=False)
    assert whole["chunks"]["count"] == 1
    a, b = results_of(summary), results_of(whole)
    a["study"].pop("chunk_size"), b["study"].pop("chunk_size")
    assert a == b
    assert summary["metrics"]["itae"]["n"] == 10 and summary["failures"]["unstable"]["count"] == 0


@pytest.mark.slow
def test_interrupted_study_resumes_without_recomputing(chunked, tmp_path):
    _, reference = chunked

    class Interrupt(Exception):
        pass

    def stop_after_second(k):
        if k == 1:
            raise Interrupt

    with pytest.raises(Interrupt):
        run_study(STUDY, tmp_path, progress=False, figures=False, after_chunk=stop_after_second)
    files = sorted((tmp_path / "chunks").glob("chunk_*.npz"))
    assert [p.name for p in files] == ["chunk_00000.npz", "chunk_00001.npz"]
    assert not (tmp_path / "summary.json").exists()
    stamps = {p.name: p.stat().st_mtime_ns for p in files}
    resumed = run_study(STUDY, tmp_path, progress=False, figures=False)
    assert resumed["chunks"] == {"size": 4, "count": 3, "computed_now": 1, "loaded": 2}
    assert {p.name: p.stat().st_mtime_ns for p in files} == stamps
    assert results_of(resumed) == results_of(reference)
    assert json.loads((tmp_path / "summary.json").read_text())["n_runs"] == 10
    # A different study in the same folder does not reuse the chunks.
    other = run_study(Study(**{**vars(STUDY), "seed": 6}), tmp_path, progress=False, figures=False)
    assert other["chunks"]["computed_now"] == 3


@pytest.mark.slow
def test_four_forced_cpu_devices_give_the_same_summary(chunked, tmp_path):
    _, reference = chunked
    code = (
        "import jax, json, sys; jax.config.update('jax_enable_x64', True)\n"
        "from tuning.montecarlo.study import Study; from tuning.montecarlo import run_study\n"
        "assert len(jax.devices()) == 4\n"
        f"s = run_study(Study(**{vars(STUDY)!r}), sys.argv[1], progress=False, figures=False)\n"
        "print(json.dumps(s))\n"
    )
    env = {**os.environ, "XLA_FLAGS": "--xla_force_host_platform_device_count=4", "PYTHONPATH": str(ROOT)}
    proc = subprocess.run(
        [sys.executable, "-c", code, str(tmp_path)], capture_output=True, text=True, env=env, cwd=ROOT
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    four = json.loads(proc.stdout.strip().splitlines()[-1])
    assert four["devices"]["count"] == 4
    # 10 runs in chunks of 4 rounded up to 8 (two per device): the last chunk carries 6 padding runs.
    assert four["chunks"]["size"] == 8 and four["chunks"]["count"] == 2
    assert results_of(four) == results_of(reference)


# ---------------------------------------------------------------------------------------- sensitivities


@pytest.mark.slow
def test_ad_sensitivities_match_central_differences():
    # Plant, inverter, controller and scenario parameters; a weakly damped speed loop and a light rotor
    # give every compared metric a non-zero derivative.
    names = ("motor.R", "motor.L_q", "motor.psi_f", "motor.J", "bridge.u_dc")
    names += ("controller.speed.active_damping", "scenario.load_nm")
    study = Study(n=2, parameters={n: {"tolerance": 0.1} for n in names}, **SHORT)
    runner = StudyRunner(study)
    nominal = np.array([mc_study.nominal_value(study, runner.drive, n) for n in names])
    factors = np.array([[1.1, 0.9, 1.05, 0.5, 0.95, 0.1, 1.2], [0.85, 1.1, 0.9, 0.6, 1.05, 0.15, 0.8]])
    base = nominal * factors
    jac, finite = runner.jacobian(base)
    assert np.all(finite == 1.0)
    # steps of 1e-6 of each parameter around each of the two base points, all in one forward batch
    stencils = [CentralDifferences.around(b, rel_step=1e-6, step_floor=0.0, labels=names) for b in base]
    m, _ = runner.forward(np.concatenate([np.asarray(s.points()) for s in stencils]))
    compared = ("itae", "overshoot_pct", "dip_rpm", "peak_current_a", "final_error_rpm")
    for name in compared:
        i = METRICS.index(name)
        ad = jac[:, i, :]
        scale = np.max(np.abs(ad * base))  # compare metric changes per relative parameter change
        assert scale > 0, name
        for r, stencil in enumerate(stencils):
            fd = stencil.quotients(m[name][r * stencil.size : (r + 1) * stencil.size])
            # |ad - fd| |p| <= 1e-5 scale: the absolute floor in the metric's change per relative change
            atol = 1e-5 * scale / np.abs(base[r])
            assert_gradient_close(
                ad[r], fd, names=[f"{name} / {n}" for n in names], x=base[r], rtol=0, atol=atol
            )
    # Settling time is piecewise constant in the parameters: AD gives 0 (the tornado shows it as such).
    assert np.all(jac[:, METRICS.index("settling_time_s"), :] == 0.0)


# ----------------------------------------------------------------------------------- command and files


@pytest.mark.slow
def test_command_writes_summary_and_figures_and_resumes(tmp_path, capsys):
    from pmsmjax.cli import main

    config = tmp_path / "study.toml"
    config.write_text(
        "[study]\nsensitivity_runs = 0\ndecimate = 20\n[scenario]\nduration_s = 0.06\nload_time_s = 0.03\n"
        "speed_rpm = 600.0\nload_nm = 3.0\n"
        '[parameters."motor.R"]\ntolerance = 0.2\n[parameters."motor.J"]\ndistribution = "lognormal"\n'
        "tolerance = 0.5\n"
    )
    out = tmp_path / "mc"
    args = ["montecarlo", "--n", "5", "--out", str(out), "--config", str(config), "--no-progress"]
    assert main(args + ["--chunk-size", "3"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    for key in ("n_runs", "run_time_s", "compile_time_s"):
        assert key in summary
    assert summary["n_runs"] == 5 and summary["compile_time_s"] > 0
    # No sensitivities asked for (they are tested above and drawn in notebooks/05): no tornado chart.
    assert set(summary["figures"]) == {"histograms.png", "fan_chart.png"} and summary["sensitivities"] is None
    assert all((out / f).stat().st_size > 1000 for f in summary["figures"])
    assert set(summary["parameters"]) == {"motor.R", "motor.J"}
    assert summary["parameters"]["motor.J"]["kind"] == "lognormal"
    assert "failures" in capsys.readouterr().out
    assert main(args + ["--chunk-size", "3"]) == 0
    again = json.loads((out / "summary.json").read_text())
    assert again["chunks"]["computed_now"] == 0 and results_of(again) == results_of(summary)


def test_command_help(capsys):
    from pmsmjax.cli import main

    with pytest.raises(SystemExit) as exit_info:
        main(["montecarlo", "--help"])
    assert exit_info.value.code == 0
    assert "--n" in capsys.readouterr().out
