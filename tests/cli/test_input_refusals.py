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


# --- logs as instruments and firmware tools write them ----------------------------------------------
def test_log_dialect_slips_are_refused_in_one_line(capsys, tmp_path):
    t = np.arange(200) * 1e-4
    rows = ["time;u_d;u_q"] + [f"{x:.6f};2,5;20,0".replace(".", ",", 1) for x in t]
    comma = drive(tmp_path, "comma.csv", "\n".join(rows) + "\n")
    out = tmp_path / "o"
    identify = ["identify", comma, "--pole-pairs", "4", "--out", out]
    refused(capsys, identify, "decimal comma", '[log] decimal = ","')
    for table, needles in [
        ('[log]\nformat = "vesk"\n', ["format = 'vesk'", "known: vesc"]),
        ('[log]\ndelimiter = "|"\n', ["delimiter = '|'", '"whitespace"']),
        ("[log]\nheader_row = 0\n", ["header_row = 0", "1-based line"]),
        ('[log]\ndecimal = ","\ndelimiter = ","\n', ["other than the comma"]),
        ('[log]\nencoding = "latin-1"\n', ["unknown keys ['encoding']"]),
    ]:
        config = drive(tmp_path, "c.toml", table)
        refused(capsys, [*identify, "--config", config], *needles)
        for command in (["replay", comma, "--motor", "book"], ["observe", comma, "--motor", "book",
                                                                "--observer", "smo"]):  # fmt: skip
            refused(capsys, [*command, "--config", config, "--out", out], *needles)
    argv = ["replay", comma, "--motor", "book", "--units", "time=ms", "--time-unit", "us", "--out", out]
    refused(capsys, argv, "--time-unit us contradicts")
    named = drive(tmp_path, "named.csv", "Time [ms],u_d [V],u_q [A]\n0,1,2\n0.1,1,2\n")
    refused(capsys, ["replay", named, "--motor", "book", "--out", out], "'u_q [A]'", "not a unit of u_q")
    named = drive(tmp_path, "named.csv", "Time [ms],u_d [V],u_q\n0,1,2\n0.1,1,2\n")
    refused(
        capsys, ["replay", named, "--motor", "book", "--units", "time=s", "--out", out], "contradicts", "ms"
    )
    assert not out.exists()


def test_a_column_name_with_spaces_and_brackets_on_the_command_line():
    from pmsmjax.cli.checks import key_values

    args = build_parser().parse_args(["identify", "x.csv", "--columns", "i_a=Phase A [A]", 'i_b="Ib (mA)"',
                                      "--out", "o"])  # fmt: skip
    assert key_values(args.columns, "--columns") == {"i_a": "Phase A [A]", "i_b": "Ib (mA)"}


def test_replay_reads_a_semicolon_log_in_ms_through_a_column_map(tmp_path):
    """The same log, once canonical in SI and once as a tool writes it (a preamble, semicolons, time in
    ms, currents in mA, instrument names mapped in --config), replays to the same result."""
    from pmsmjax.recorded.replay import replay_log

    t = np.arange(300) * 1e-4
    cols = {"time": t, "u_d": -2.0 + 0 * t, "u_q": 30.0 + 5 * np.sin(200 * t), "omega_m": 100.0 + 0 * t,
            "i_d": 0 * t, "i_q": 0 * t}  # fmt: skip
    si = write_csv_atomic(tmp_path / "si.csv", cols)
    lines = ["Logger;bench", "", "# exported", "Time [ms];Ud;Uq;speed;Id/mA;Iq/mA"]
    lines += [
        ";".join(f"{v:.17g}" for v in (1e3 * a, b, c, d, e, f))
        for a, b, c, d, e, f in zip(*cols.values(), strict=True)
    ]
    tool = drive(tmp_path, "tool.csv", "\n".join(lines) + "\n")
    config = drive(tmp_path, "c.toml", '[columns]\nu_d = "Ud"\nu_q = "Uq"\ni_d = "Id"\ni_q = "Iq"\n')
    from pmsmjax.cli.checks import log_reading

    args = build_parser().parse_args(["replay", str(tool), "--motor", "book", "--config", str(config),
                                      "--columns", "omega_m=speed", "--out", "o"])  # fmt: skip
    columns, units, dialect, _ = log_reading(args, set(), "replay")
    a = replay_log(si, "book", hold="stator")
    b = replay_log(tool, "book", hold="stator", columns=columns, units=units, dialect=dialect)
    for name in a:
        np.testing.assert_allclose(b[name], a[name], rtol=1e-12, atol=1e-12, err_msg=name)


DIALECTS = st.fixed_dictionaries(
    {
        "delimiter": st.sampled_from([",", ";", "\t", " "]),
        "decimal": st.sampled_from([".", ","]),
        "preamble": st.lists(
            st.sampled_from(
                ["Instrument{d}Scope", "Sample rate{d}10 kHz", "", "# note", "% exported", "Channels{d}4"]
            ),
            max_size=4,
        ),  # fmt: skip
        "suffixes": st.booleans(),
        "trailing": st.booleans(),
        "edit": st.one_of(st.none(), st.tuples(st.integers(0, 30), st.text(max_size=6))),
    }
)


@settings(max_examples=60, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow])  # fmt: skip
@given(dialect=DIALECTS)
def test_a_log_in_any_dialect_reads_as_the_canonical_one_or_is_refused_in_one_line(dialect):
    """A valid dq log written with a random delimiter, preamble, decimal mark, unit suffixes (time in ms,
    currents in mA) and trailing delimiter reads to the canonical log's columns (the decimal comma stated
    in [log]); with one line garbled it reads or is refused in one line."""
    import tempfile
    from pathlib import Path

    from pmsmjax.io.csv_dialect import CsvDialect
    from pmsmjax.spec.validation import ParameterError
    from tuning.identify.log import load_drive_log

    d, decimal = dialect["delimiter"], dialect["decimal"]
    if d == ",":
        decimal = "."
    t = np.arange(40) * 1e-4
    cols = {"time": t, "u_d": 1.5 + t, "u_q": 20.0 - t, "i_d": 0.25 + 0 * t, "i_q": 2.0 + 10 * t,
            "omega_m": 50.0 + 0 * t}  # fmt: skip
    scale = {"time": 1e3, "i_d": 1e3, "i_q": 1e3} if dialect["suffixes"] else {}
    names = {"time": "Time [ms]", "i_d": "i_d/mA", "i_q": "i_q (mA)"} if dialect["suffixes"] else {}
    if d == " ":  # names without spaces in a whitespace-separated file
        names = {k: v.replace(" ", "") for k, v in names.items()}
    sep = "  " if d == " " else d
    end = d if dialect["trailing"] and d != " " else ""
    fmt = lambda v: f"{v:.15g}".replace(".", ",") if decimal == "," else f"{v:.15g}"
    lines = [p.format(d=sep if d != " " else ":") for p in dialect["preamble"]]
    lines.append(sep.join(names.get(k, k) for k in cols) + end)
    lines += [sep.join(fmt(scale.get(k, 1.0) * cols[k][r]) for k in cols) + end for r in range(t.size)]
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "log.csv"
        path.write_text("\n".join(lines) + "\n")
        log = load_drive_log(path, 4, dialect=CsvDialect(decimal=decimal))
        np.testing.assert_allclose(log.time, t, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(log.i_dq[:, 1], cols["i_q"], rtol=1e-12)
        np.testing.assert_allclose(log.u_dq[:, 0], cols["u_d"], rtol=1e-12)
        if dialect["edit"] is not None:
            k, text = dialect["edit"]
            k = k % len(lines)
            lines[k] = lines[k][: len(lines[k]) // 2] + text
            path.write_text("\n".join(lines) + "\n")
            try:
                load_drive_log(path, 4, dialect=CsvDialect(decimal=decimal))
            except ParameterError as err:
                assert "\n" not in str(err) and str(err)
