"""What a user can type never ends in an internal error: each input below is refused with one line, exit
2, naming the flag or file field and the fix, before any file is written; and random flags on every
command either parse or are refused in one line (hypothesis, parsing only: no command runs)."""

import argparse

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pmsmjax.cli import SUBCOMMANDS, build_parser, main
from pmsmjax.io.logs import write_csv_atomic

MOTORS = __import__("pathlib").Path(__file__).resolve().parents[2] / "pmsmjax" / "presets" / "motors"
BOOK = (MOTORS / "book.toml").read_text()
MAP = (MOTORS / "saturated_ipm.toml").read_text()


def refused(capsys, argv, *needles):
    try:
        code = main([str(a) for a in argv])
    except SystemExit as done:
        code = done.code
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err
    assert lines[0].startswith(f"pmsmjax {argv[0]}: error: ") and "Traceback" not in err
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


def drive(tmp_path, name, text):
    path = tmp_path / name
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    return path


@pytest.mark.parametrize(
    "case, needles",
    [
        ("duration", ["[scenario] duration_s", "control periods", "at most 1000"]),
        ("nested", ["nest too deeply"]),
        ("binary_map", ["not a text file", ".npz or .mat"]),
        ("folder_map", ["is a folder"]),
        ("mwb_map", ["psi_d, psi_q", "mWb", "divide them by 1000"]),
        ("huge_J", ["[motor] J", "beyond any physical value"]),
        ("scenario_speed", ["[scenario] speed_rpm", "give at most"]),
        ("quoted", ["[inverter] u_dc_v", "a string", "without quotes"]),
    ],
)
def test_drive_file_slips_are_refused_naming_the_field(capsys, tmp_path, case, needles):
    files = {
        "duration": BOOK.replace("duration_s = 0.4", "duration_s = 1e6"),
        "nested": "[motor]\nR = " + "[" * 3000 + "]" * 3000 + "\n",
        "huge_J": BOOK.replace("J = 0.003 ", "J = 1e300 "),
        "scenario_speed": BOOK.replace("[scenario]\nspeed_rpm = 1000.0", "[scenario]\nspeed_rpm = 99999.0"),
        "quoted": BOOK.replace("u_dc_v = 311.0 ", 'u_dc_v = "311.0" '),
    }
    if case in ("binary_map", "folder_map", "mwb_map"):
        target = {"binary_map": "bin.csv", "folder_map": "adir", "mwb_map": "mwb.csv"}[case]
        (tmp_path / "adir").mkdir()
        drive(tmp_path, "bin.csv", bytes(range(256)) * 4)
        rows = (MOTORS / "saturated_ipm_map.csv").read_text().splitlines()
        in_mwb = lambda r: ",".join(v if k < 2 else repr(1e3 * float(v)) for k, v in enumerate(r.split(",")))
        scaled = [r if r.startswith(("#", "i_d")) else in_mwb(r) for r in rows]
        drive(tmp_path, "mwb.csv", "\n".join(scaled) + "\n")
        files[case] = MAP.replace('flux_map = "saturated_ipm_map.csv"', f'flux_map = "{target}"')
    path = drive(tmp_path, f"{case}.toml", files[case])
    out = tmp_path / "out"
    refused(capsys, ["demo", "--motor", path, "--out", out], *needles)
    assert not out.exists()


def test_bom_in_drive_file_and_flux_map_is_read(tmp_path):
    from pmsmjax.io.drive_files import drive_spec

    bom = b"\xef\xbb\xbf"
    drive(tmp_path, "map.csv", bom + (MOTORS / "saturated_ipm_map.csv").read_bytes())
    text = MAP.replace('flux_map = "saturated_ipm_map.csv"', 'flux_map = "map.csv"')
    spec = drive_spec(drive(tmp_path, "m.toml", bom + text.encode()))
    assert spec.flux_map is not None
    assert drive_spec(drive(tmp_path, "b.toml", bom + BOOK.encode())).motor["R"] == 0.958


@pytest.mark.parametrize(
    "argv, needles",
    [
        (["demo", "--out", ""], ["--out is empty", "--out runs"]),
        (["demo", "--out", "x" * 300], ["--out", "300 bytes", "shorter name"]),
        (["demo", "--load-nm=-1e6"], ["--load-nm -1e+06", "current limit", "at most"]),
        (["demo", "--duration-s", "2000"], ["--duration-s 2000", "at most 1000 s"]),
    ],
)
def test_flag_slips_are_refused(capsys, tmp_path, monkeypatch, argv, needles):
    monkeypatch.chdir(tmp_path)
    refused(capsys, argv, *needles)
    assert list(tmp_path.iterdir()) == []


def test_dangling_symlink_as_out_is_refused(capsys, tmp_path):
    link = tmp_path / "runs"
    link.symlink_to(tmp_path / "gone")
    refused(capsys, ["demo", "--out", link], "symbolic link", "does not exist")


def test_gains_far_from_the_design_rule_are_refused(capsys, tmp_path):
    gains = drive(tmp_path, "g.toml", '[gains]\n"controller.speed.kp" = 1e30\n')
    refused(capsys, ["demo", "--gains", gains, "--out", tmp_path / "o"], "controller.speed.kp", "design-rule")
    quoted = drive(tmp_path, "q.toml", '[gains]\n"controller.speed.kp" = "0.1"\n')
    refused(capsys, ["demo", "--gains", quoted, "--out", tmp_path / "o"], "without quotes")


def test_logs_without_excitation_or_with_a_gap_or_a_missing_mapped_column(capsys, tmp_path):
    t = np.arange(2000) * 1e-4
    z = 0 * t
    zero = write_csv_atomic(
        tmp_path / "zero.csv", {"time": t, "u_alpha": z, "u_beta": z, "i_alpha": z, "i_beta": z}
    )
    refused(
        capsys,
        ["observe", zero, "--motor", "book", "--observer", "smo", "--out", tmp_path / "o"],
        "no excitation",
    )
    gap = write_csv_atomic(
        tmp_path / "gap.csv", {"time": np.r_[t[:1000], t[1000:] + 0.01], "u_d": z + 2, "u_q": z + 20}
    )
    refused(capsys, ["replay", gap, "--motor", "book", "--out", tmp_path / "r"], "gap of 10.1 ms", "row 1000")
    ud = write_csv_atomic(tmp_path / "ud.csv", {"time": t, "u_d": z + 2, "u_q": z + 20})
    argv = ["identify", ud, "--pole-pairs", "4", "--columns", "u_d=nonexist", "--out", tmp_path / "i"]
    line = refused(capsys, argv, "u_d=nonexist", "no column 'nonexist'")
    assert "--columns u_d=u_d" not in line
    assert not any((tmp_path / d).exists() for d in "ori")


# --- random flags: a normal parse or a one-line exit 2, never an internal error ---------------------
FLAGS = sorted(
    {s for cmd in build_parser()._subparsers._group_actions[0].choices.values() for a in cmd._actions
     for s in a.option_strings if s.startswith("--") and s != "--help"}
)  # fmt: skip
WORDS = st.one_of(
    st.sampled_from(FLAGS),
    st.sampled_from(["0", "-1", "1e308", "nan", "inf", "", " ", "=", "--", "a=b", "x" * 300, "1.5", "-1e6"]),
    st.text(max_size=12),
)


@settings(max_examples=150, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow])  # fmt: skip
@given(command=st.sampled_from([c.replace("_", "-") for c in SUBCOMMANDS]), words=st.lists(WORDS, max_size=6))
def test_random_flags_parse_or_are_refused_in_one_line(command, words):
    import contextlib
    import io

    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            args = build_parser().parse_args([command, *words])
        except SystemExit as done:
            assert done.code in (0, 2), err.getvalue()
            if done.code == 2:
                lines = err.getvalue().strip().splitlines()
                assert len(lines) == 1 and ": error: " in lines[0], err.getvalue()
            return
    assert isinstance(args, argparse.Namespace) and callable(args.func)


def test_demo_at_zero_speed_reference_runs_and_says_what_it_cannot_define(capsys, tmp_path):
    """A zero speed step has no rise time or overshoot: the summary holds null for them and the console
    says n/a (it once formatted a None after writing complete-looking files)."""
    import json

    out = tmp_path / "out"
    code = main(["demo", "--speed-rpm", "0", "--duration-s", "0.05", "--load-time-s", "0.02", "--no-figures",
                 "--out", str(out)])  # fmt: skip
    console = capsys.readouterr()
    assert code == 0, console.err
    assert "n/a" in console.out and "Traceback" not in console.err
    metrics = json.loads((out / "summary.json").read_text())["metrics"]
    assert any(value is None for value in metrics.values())
    assert all(
        value is None or np.isfinite(value) for value in metrics.values() if not isinstance(value, str)
    )
