"""Every command survives a careless user.

Each refusal case asserts: exit status 2, exactly one line on stderr that names the flag or file field and
the fix, no traceback, no NumPy repr, and no output file written. Most refusals happen before JAX starts
(a subprocess test checks that ``pmsmjax --help`` and a refused flag never import it). The runs at the end
check what a careless but valid request gets: a run that cannot reach its reference says so in
summary.json and on the console, tuned gains reach demo, Ctrl-C during tune leaves a valid checkpoint and
one line, and the help texts give every default.
"""

import argparse
import ast
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from pmsmjax.cli import build_parser, main
from pmsmjax.io.logs import write_csv_atomic

#: What a quick start must not import: JAX and the libraries on it, and the heavy scientific stack.
HEAVY_MODULES = ("jax", "jaxlib", "equinox", "optax", "optimistix", "diffrax", "scipy", "matplotlib")

MOTOR_MH = "R = 0.958\nL_d = 5.25\nL_q = 5.25\npsi_f = 0.1827\npole_pairs = 4\nJ = 0.003\nB = 0.008\n"


@pytest.fixture
def files(tmp_path):
    """Inputs a careless user has lying around."""
    t = np.arange(400) * 1e-4
    ones = np.ones_like(t)
    f = {"file": tmp_path / "afile", "mH": tmp_path / "motor_mH.toml", "dir": tmp_path / "adir"}
    f["file"].write_text("x")
    f["mH"].write_text(MOTOR_MH)
    f["dir"].mkdir()
    f["log"] = write_csv_atomic(tmp_path / "log.csv", {"time": t, "u_d": 2 * ones, "u_q": 20 * ones})
    f["log_ms"] = write_csv_atomic(tmp_path / "ms.csv", {"time": 1e3 * t, "u_d": 2 * ones, "u_q": 20 * ones})
    f["log_omega"] = write_csv_atomic(
        tmp_path / "omega.csv", {"time": t, "u_d": 2 * ones, "u_q": 20 * ones, "omega": 50 * ones}
    )
    f["log_back"] = write_csv_atomic(
        tmp_path / "back.csv", {"time": np.r_[t[:10], t[5], t[11:]], "u_d": ones, "u_q": ones}
    )
    idc = {"time": t, "u_d": ones, "u_q": ones, "i_d": ones, "i_q": ones, "theta_e": 0 * t}
    f["id_omgea"] = write_csv_atomic(tmp_path / "id_omgea.csv", {**idc, "omgea_m": ones})
    f["id_ms"] = write_csv_atomic(tmp_path / "id_ms.csv", {**idc, "time": 1e3 * t, "omega_m": 0 * t})
    f["smc_gains"] = tmp_path / "smc_gains.toml"
    f["smc_gains"].write_text('[gains]\n"controller.speed.c" = 60.0\n')
    f["pi_gains_as_names"] = f["smc_gains"]
    f["bad_checkpoint"] = tmp_path / "tune_resume"
    f["bad_checkpoint"].mkdir()
    (f["bad_checkpoint"] / "checkpoint.npz").write_bytes(b"not an npz")
    return f


def refused(capsys, argv, *needles, outputs=()):
    """Run ``argv``; assert exit 2, one line naming ``needles``, no traceback, no output written."""
    before = {p: sorted(os.listdir(p)) if p.is_dir() else None for p in outputs}
    try:
        code = main([str(a) for a in argv])
    except SystemExit as done:  # refused while parsing, as argparse does
        code = done.code
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert code == 2, err
    assert len(lines) == 1, err
    line = lines[0]
    assert line.startswith(f"pmsmjax {argv[0]}: error: "), line
    assert "Traceback" not in err and "np.float64" not in line and "array(" not in line, line
    for needle in needles:
        assert needle in line, (needle, line)
    for p, listing in before.items():  # nothing created, nothing added
        assert (sorted(os.listdir(p)) if p.is_dir() else None) == listing, p
    return line


# --------------------------------------------------------------------------------------------------
# flags: a value the user typed, named as typed, in the user's unit
# --------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "argv, needles",
    [
        (["demo", "--load-nm", "nan"], ["--load-nm", "finite", "N m"]),
        (["demo", "--speed-rpm", "fast"], ["--speed-rpm", "not a number"]),
        (["demo", "--speed-rpm", "-99999"], ["--speed-rpm", "give at most", "r/min", "--field-weakening"]),
        (
            ["demo", "--load-time-s", "5"],
            ["--load-time-s", "[scenario] duration_s", "give a time below 0.4 s"],
        ),
        (["demo", "--duration-s", "-1"], ["--duration-s", "> 0 s"]),
        (["demo", "--substeps", "0"], ["--substeps", ">= 1"]),
        (["demo", "--duration-s", "0.30005"], ["--duration-s", "whole number", "give e.g. 0.3"]),
        (["demo", "--decimate", "7"], ["--decimate", "divisor"]),
        (["demo", "--control", "foc"], ["--control", "invalid choice"]),
        (["demo", "--band-a", "0.5"], ["--band-a", "does not apply to --control pi"]),
        (["demo", "--motor", "nosuch"], ["--motor nosuch", "preset", "drive file"]),
        (["demo", "--gains", "nosuch.toml"], ["--gains nosuch.toml", "does not exist"]),
        (["pwm-compare", "--dead-time-us", "-2"], ["--dead-time-us", ">= 0 us"]),
        (["pwm-compare", "--speed-rpm", "1234"], ["--speed-rpm", "whole number", "e.g."]),
        (["pwm-compare", "--speed-rpm", "5000"], ["--speed-rpm 5000", "top speed", "about 2119 r/min"]),
        (["pwm-compare", "--load-nm", "40"], ["--load-nm 40", "current limit", "at most"]),
        (["pwm-compare", "--modulators", "spwm"], ["--modulators", "invalid choice"]),
        (["compare", "--speed-rpm", "5000"], ["--speed-rpm 5000", "top speed"]),
        (["compare", "--control", "pi,foc"], ["--control", "foc", "choose from"]),
        (["compare", "--load-time-s", "1"], ["--load-time-s", "--duration-s"]),
        (["tune", "--duration-s", "0.5", "0.3"], ["--duration-s", "LOW is above HIGH"]),
        (["tune", "--learning-rate", "-0.1"], ["--learning-rate", "> 0"]),
        (["tune", "--iterations", "1.5"], ["--iterations", "not a whole number"]),
        (["tune", "--config", "nosuch.toml"], ["--config nosuch.toml", "does not exist"]),
        (["montecarlo", "--devices", str((os.cpu_count() or 1) + 1)], ["--devices", "give at most"]),
        (["montecarlo", "--n", "0"], ["--n", ">= 1"]),
        (["montecarlo", "--config", "nosuch.toml"], ["--config nosuch.toml", "does not exist"]),
        (["identify", "nosuch.csv", "--pole-pairs", "4", "--out", "o"], ["log nosuch.csv", "does not exist"]),
        (["bench", "--json", "nosuch_dir/b.json"], ["--json", "does not exist"]),
    ],
)
def test_bad_flag_is_one_line_naming_flag_and_fix(capsys, tmp_path, monkeypatch, argv, needles):
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "out"
    has_out = argv[0] not in ("bench",) and "--out" not in argv
    refused(capsys, argv + (["--out", out] if has_out else []), *needles, outputs=[out, tmp_path])


# --------------------------------------------------------------------------------------------------
# files: --out, motor files, logs, gains, checkpoints
# --------------------------------------------------------------------------------------------------
#: Every command that writes into ``--out``, with the other arguments it needs (``{log}``: a log file).
OUT_COMMANDS = [
    ["demo"],
    ["compare"],
    ["pwm-compare"],
    ["tune"],
    ["montecarlo", "--n", "8"],
    ["replay", "{log}", "--motor", "book"],
    ["identify", "{log}", "--pole-pairs", "4"],
]


@pytest.mark.parametrize("argv", OUT_COMMANDS)
@pytest.mark.parametrize("where", ["file", "inside_file"])
def test_out_naming_a_file_is_refused_before_any_work(capsys, files, argv, where):
    out = files["file"] if where == "file" else files["file"] / "sub"
    argv = [a.format(log=files["log"]) for a in argv]
    refused(
        capsys,
        [*argv, "--out", out],
        "--out",
        "existing file",
        "give a folder name",
        outputs=[files["dir"].parent],
    )
    assert files["file"].read_text() == "x"


def test_out_naming_a_file_is_refused_before_jax_is_imported(files):
    """Before any work: in a fresh interpreter every command refuses such an ``--out`` (exit 2) without
    importing JAX or any other of :data:`HEAVY_MODULES`, so nothing is compiled (rather than compiling
    for up to 20 s and then printing a traceback)."""
    code = (
        "import json, sys\nfrom pmsmjax.cli import main\n"
        f"heavy = {HEAVY_MODULES!r}\n"
        "for argv in json.loads(sys.argv[1]):\n"
        "    assert main(argv) == 2, argv\n"
        "    loaded = [m for m in heavy if m in sys.modules]\n"
        "    assert not loaded, (argv, loaded)\n"
    )
    runs = [
        [*(a.format(log=files["log"]) for a in argv), "--out", str(out)]
        for argv in OUT_COMMANDS
        for out in (files["file"], files["file"] / "sub")
    ]
    r = subprocess.run(
        [sys.executable, "-c", code, json.dumps(runs)], capture_output=True, text=True, check=False
    )
    assert r.returncode == 0, r.stderr
    assert r.stderr.count("existing file") == len(runs), r.stderr
    assert files["file"].read_text() == "x"


def test_bench_json_naming_a_folder_is_refused(capsys, files):
    refused(capsys, ["bench", "--json", files["dir"]], "--json", "is a folder", "give a file name")


def test_motor_in_mH_is_refused_with_the_unit_named(capsys, files, tmp_path):
    for cmd in (["demo"], ["compare"], ["replay", files["log"]]):
        line = refused(
            capsys,
            [*cmd, "--motor", files["mH"], "--out", tmp_path / "o"],
            "L_d = 5.25 H",
            "looks like mH",
            "0.00525",
            "trust_units = true",
            "--trust-units",
            outputs=[tmp_path / "o"],
        )
        assert str(files["mH"]) in line


def test_trust_units_lets_a_genuine_odd_motor_through(capsys, files, tmp_path):
    """A 1.2 H motor is refused as a likely unit mistake; ``trust_units = true`` in its file lets it in."""
    motor = tmp_path / "odd.toml"
    motor.write_text(MOTOR_MH.replace("L_d = 5.25", "L_d = 1.2").replace("L_q = 5.25", "L_q = 1.2"))
    refused(capsys, ["demo", "--motor", motor, "--out", tmp_path / "o"], "L_d = 1.2 H", "--trust-units")
    motor.write_text(motor.read_text() + "trust_units = true\n")
    from pmsmjax.io.motor_files import read_motor_file

    assert read_motor_file(motor)["L_d"] == 1.2


@pytest.mark.parametrize(
    "key, needles",
    [
        ("log_ms", ["time looks like it is in ms", "--time-unit ms", "--trust-units"]),
        ("log_omega", ["'omega'", "'omega_m'", "imposed mechanical speed", "rename"]),
        ("log_back", ["strictly increasing", "row 10", "sort the rows"]),
    ],
)
def test_replay_refuses_a_log_it_would_misread(capsys, files, tmp_path, key, needles):
    out = tmp_path / "o"
    refused(capsys, ["replay", files[key], "--motor", "book", "--out", out], *needles, outputs=[out])


def test_replay_reports_unused_columns_and_the_hold_it_chose(capsys, tmp_path):
    t = np.arange(50) * 1e-4
    log = write_csv_atomic(
        tmp_path / "l.csv", {"time": t, "u_d": 0 * t, "u_q": 10 + 0 * t, "speed_rpm": 0 * t, "note": 0 * t}
    )
    assert main(["replay", str(log), "--motor", "book", "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "columns not used: speed_rpm, note" in out and "hold: stator" in out


@pytest.mark.parametrize(
    "key, needles",
    [
        ("id_omgea", ["'omgea_m'", "'omega_m'", "--columns omega_m=omgea_m"]),
        ("id_ms", ["sampling step", "--units time=ms"]),
    ],
)
def test_identify_refuses_a_log_it_would_misread(capsys, files, tmp_path, key, needles):
    out = tmp_path / "o"
    refused(capsys, ["identify", files[key], "--pole-pairs", "4", "--out", out], *needles, outputs=[out])


@pytest.mark.parametrize(
    "argv, needles",
    [
        (["--fix", "L_d=abc"], ["--fix L_d=abc", "not a finite number", "e.g. L_d=0.0041"]),
        (["--fix", "L_d"], ["--fix L_d", "not KEY=VALUE"]),
        (["--pole-pairs", "0"], ["--pole-pairs", ">= 1"]),
    ],
)
def test_identify_options(capsys, files, tmp_path, argv, needles):
    out = tmp_path / "o"
    base = ["identify", files["id_omgea"], "--out", out]
    refused(capsys, base + (["--pole-pairs", "4"] if "--pole-pairs" not in argv else []) + argv, *needles)


def test_gains_of_another_control_are_refused(capsys, files, tmp_path):
    out = tmp_path / "o"
    refused(
        capsys,
        ["demo", "--gains", files["smc_gains"], "--out", out],
        "--gains",
        "controller.speed.c",
        "--control pi",
        outputs=[out],
    )


def test_tune_gains_file_given_as_names_points_at_start_gains(capsys, files, tmp_path):
    refused(capsys, ["tune", "--gains", files["smc_gains"], "--out", tmp_path / "o"], "--start-gains")


def test_unreadable_checkpoint_says_how_to_start_fresh(capsys, files):
    out = files["bad_checkpoint"]
    argv = ["tune", "--out", out, "--train", "1", "--heldout", "1", "--iterations", "1", "--no-progress"]
    refused(capsys, argv, "checkpoint", "--fresh", outputs=[out])


def test_checkpoint_of_other_settings_says_how_to_start_fresh(tmp_path):
    from pmsmjax.spec.validation import ParameterError
    from tuning.autotune.tuner import _load_checkpoint

    path = tmp_path / "checkpoint.npz"
    np.savez(path, fingerprint=np.asarray("another problem"))
    with pytest.raises(ParameterError) as err:
        _load_checkpoint(path, "this problem", None)
    assert "different tuning problem" in str(err.value) and "--fresh" in str(err.value)


# --------------------------------------------------------------------------------------------------
# no silent nonsense: a run that cannot do what was asked says so
# --------------------------------------------------------------------------------------------------
@pytest.mark.slow
def test_unreachable_speed_is_flagged_with_cause_and_remedy(capsys, tmp_path):
    out = tmp_path / "o"
    assert main(["demo", "--speed-rpm", "5000", "--out", str(out), "--no-figures"]) == 0
    console = capsys.readouterr().out
    op = json.loads((out / "summary.json").read_text())["operating_point"]
    assert op["ok"] is False and op["voltage_limited_share"] > 0.8
    flags = {f["segment"]: f for f in op["flags"]}
    end = flags["at the end"]
    assert end["flag"] == "speed_not_reached" and end["limit"] == "voltage"
    assert (
        "2119 r/min" in end["cause"]
        and "--field-weakening" in end["remedy"]
        and "--speed-rpm" in end["remedy"]
    )
    assert console.count("WARNING speed_not_reached") == 2


@pytest.mark.slow
def test_a_reachable_run_has_no_flags_and_documented_units(tmp_path):
    out = tmp_path / "o"
    assert (
        main(["demo", "--out", str(out), "--no-figures", "--duration-s", "0.3", "--load-time-s", "0.15"]) == 0
    )
    summary = json.loads((out / "summary.json").read_text())
    assert summary["operating_point"]["ok"] is True and summary["operating_point"]["flags"] == []
    header = (out / "trace.csv").read_text().splitlines()[0].split(",")
    assert set(header) == set(summary["trace_columns"])
    data = np.genfromtxt(out / "trace.csv", delimiter=",", names=True)
    np.testing.assert_allclose(data["speed_ref_rpm"], data["speed_ref"] * 30 / np.pi, rtol=1e-12)
    np.testing.assert_allclose(data["speed_rpm"], data["omega_m"] * 30 / np.pi, rtol=1e-12)
    assert "final_error_rpm" in summary["definitions"]


@pytest.mark.slow
def test_field_weakening_top_speed_matches_the_simulated_drive(tmp_path):
    """The steady-state limit model (pure algebra) against the closed-loop simulation: the drive asked
    for 3000 r/min at 10 N m with field weakening settles at the predicted top speed."""
    from pmsmjax.analysis.operating_point import FIELD_WEAKENING_MARGIN
    from pmsmjax.presets.book_constants import BOOK_MOTOR
    from pmsmjax.spec.steady_state import field_weakening_top_speed_rpm

    out = tmp_path / "o"
    argv = ["demo", "--speed-rpm", "3000", "--field-weakening", "--out", str(out), "--no-figures"]
    assert main(argv) == 0
    op = json.loads((out / "summary.json").read_text())["operating_point"]
    reached = op["segments"][-1]["speed_rpm"]
    u_lim = FIELD_WEAKENING_MARGIN * 311.0 / np.sqrt(3.0)
    predicted = field_weakening_top_speed_rpm(BOOK_MOTOR, u_lim, 15.0, 10.0)
    assert reached == pytest.approx(predicted, rel=0.01)
    assert op["flags"][0]["limit"] == "voltage" and f"{predicted:.0f} r/min" in op["flags"][0]["cause"]


def test_tuned_gains_reach_demo(tmp_path):
    gains = tmp_path / "gains.toml"
    gains.write_text('[gains]\n"controller.speed.kp" = 0.05\n"controller.speed.ki" = 0.5\n')
    args = ["--out", "{}", "--no-figures", "--duration-s", "0.3", "--load-time-s", "0.15"]
    a, b = tmp_path / "a", tmp_path / "b"
    assert main(["demo", *[x.format(a) for x in args]]) == 0
    assert main(["demo", "--gains", str(gains), *[x.format(b) for x in args]]) == 0
    sa, sb = (json.loads((d / "summary.json").read_text()) for d in (a, b))
    assert sb["drive"]["gains"] == str(gains)
    # A much softer speed loop (design rule: kp 0.137 A s/rad): far from the reference, and said so.
    assert sb["metrics"]["final_speed_rpm"] < 0.5 * sa["metrics"]["final_speed_rpm"]
    assert sa["operating_point"]["ok"] and not sb["operating_point"]["ok"]


# --------------------------------------------------------------------------------------------------
# Ctrl-C, warnings and failures of the program itself: one line each
# --------------------------------------------------------------------------------------------------
@pytest.mark.slow
def test_ctrl_c_during_tune_is_one_line_exit_130_and_a_valid_checkpoint(capsys, tmp_path, monkeypatch):
    import tuning.autotune.job as job

    real_tune = job.tune

    def interrupted_at_3(*args, **kwargs):
        def stop(it, cost):
            if it == 3:
                raise KeyboardInterrupt

        return real_tune(*args, **{**kwargs, "callback": stop})

    out = tmp_path / "tune"
    argv = ["tune", "--out", str(out), "--train", "2", "--heldout", "2", "--iterations", "6", "--no-progress"]
    argv += ["--duration-s", "0.2", "0.2", "--method", "adam", "--eval-substeps", "1"]
    monkeypatch.setattr(job, "tune", interrupted_at_3)
    assert main(argv) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("pmsmjax tune: interrupted: at iteration 3 of 6")
    assert "rerun the same command to resume" in err[0] and "Traceback" not in err[0]
    with np.load(out / "checkpoint.npz") as ck:
        assert int(ck["iteration"]) == 3 and ck["history"].shape == (3,)
    assert sorted(os.listdir(out)) == ["checkpoint.npz"]
    monkeypatch.setattr(job, "tune", real_tune)
    assert main(argv) == 0
    assert "resumed from iteration 3" in capsys.readouterr().out
    assert json.loads((out / "result.json").read_text())["iterations"] == 6


def test_warnings_and_internal_errors_are_one_line(capsys, monkeypatch):
    import warnings

    import pmsmjax.cli.replay as replay_cli

    # add_parser binds ``run`` when main builds the parser, so patching the module's ``run`` is enough.
    monkeypatch.setattr(replay_cli, "run", lambda args: warnings.warn("a\nb", stacklevel=1) or 0)
    argv = ["replay", "x.csv", "--motor", "book", "--out", "o"]
    assert main(argv) == 0
    assert capsys.readouterr().err == "pmsmjax replay: warning: a b\n"
    monkeypatch.setattr(replay_cli, "run", lambda args: 1 / 0)
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "internal error: ZeroDivisionError" in err and "Traceback" not in err


# --------------------------------------------------------------------------------------------------
# usability: start-up without JAX, defaults in every help text
# --------------------------------------------------------------------------------------------------
def test_help_and_refusals_do_not_import_jax():
    """``--help`` and the refusals load none of :data:`HEAVY_MODULES` (a quick start: 0.2 s idle)."""
    code = (
        "import sys\nfrom pmsmjax.cli import main\n"
        "try:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
        "try:\n    main(['demo', '--load-nm', 'nan'])\nexcept SystemExit as e:\n    assert e.code == 2\n"
        "assert main(['pwm-compare', '--speed-rpm', '5000']) == 2\n"
        "print(sorted({m.split('.')[0] for m in sys.modules}))"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert r.returncode == 0, r.stderr
    loaded = set(ast.literal_eval(r.stdout.strip().splitlines()[-1]))
    assert "pmsmjax" in loaded and loaded.isdisjoint(HEAVY_MODULES), sorted(loaded & set(HEAVY_MODULES))


def test_every_option_help_gives_its_default():
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    missing = []
    for name, p in sub.choices.items():
        for action in p._actions:
            if (
                action.option_strings
                and not isinstance(action, (argparse._HelpAction, argparse._StoreTrueAction))
                and not action.required
            ):
                if "default" not in (action.help or ""):
                    missing.append(f"{name} {action.option_strings[0]}")
    assert missing == []


def test_replay_and_identify_share_one_default_hold(tmp_path, monkeypatch):
    """Replay's flag default, and what identify passes on when given none (captured where it reads the
    log), are both :data:`pmsmjax.recorded.replay.DEFAULT_HOLD`."""
    from pmsmjax.recorded import replay
    from tuning.identify import pipeline

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    flag = next(a for a in sub.choices["replay"]._actions if a.dest == "hold")
    assert flag.default == replay.DEFAULT_HOLD == "auto"
    seen = {}

    def capture(path, pole_pairs, **kwargs):
        seen.update(kwargs)
        raise KeyboardInterrupt

    monkeypatch.setattr(pipeline, "load_drive_log", capture)
    with pytest.raises(KeyboardInterrupt):
        pipeline.identify_file(tmp_path / "log.csv", tmp_path / "out", 4)
    assert seen["hold"] == replay.DEFAULT_HOLD
