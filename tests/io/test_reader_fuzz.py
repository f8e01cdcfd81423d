"""Property-based fuzzing of the readers of user files: random corruptions of valid drive files
(:func:`pmsmjax.io.drive_files.drive_spec`) and of valid log CSVs (:func:`pmsmjax.io.logs.read_log`,
:func:`tuning.identify.log.load_drive_log`, and ``pmsmjax identify`` through :func:`pmsmjax.cli.main`)
either still read or are refused with a one-line :class:`ParameterError`; no other exception ever
escapes (a ``KeyError``, ``IndexError`` or ``TypeError`` here is a reader that trusted its input).

Derandomised (the same examples every run) and without an example database, so the suite stays
reproducible and writes nothing outside its temporary folders; a failure prints its minimal example.
"""

import contextlib
import io
import math
import re
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import pmsmjax.cli
from pmsmjax.io.drive_files import PRESET_FOLDER, drive_spec
from pmsmjax.io.logs import read_log
from pmsmjax.spec.validation import ParameterError

FUZZ = settings(
    max_examples=25,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow],
)
NUMBER = re.compile(r"(?<![\w.])-?\d+(\.\d+)?(e-?\d+)?(?![\w.])")
#: Valid drive files and the phase count a command would read them for.
DRIVE_FILES = [
    ("book.toml", 3),
    ("servo_400w_48v.toml", 3),
    ("industrial_5k6w_540v.toml", 3),
    ("outer_rotor_24v.toml", 3),
    ("six_phase_book.toml", 6),
    ("five_phase_book.toml", 5),
]
#: Values of every TOML type (and the special floats) that may replace a value.
OTHER_VALUES = ['"text"', "true", "false", "[1.0, 2.0]", "[]", "{ a = 1 }", "nan", "inf", "-inf", "0", "-1.0"]


def assert_refused_or_read(call):
    """Run ``call()``: it returns, or raises a one-line ParameterError."""
    try:
        return call()
    except ParameterError as err:
        message = str(err)
        assert message and "\n" not in message and "\r" not in message, repr(message)
        return None


def log_csv_text(n: int = 120) -> str:
    """A valid dq log: 0.1 ms rows, a speed ramp with its electrical angle (4 pole pairs), smooth voltages
    and currents."""
    t = np.arange(n) * 1e-4
    w = 100.0 * (1.0 - np.exp(-t / 0.005))
    theta = np.mod(4.0 * np.cumsum(w) * 1e-4, 2.0 * np.pi)
    cols = {
        "time": t,
        "u_d": 5.0 * np.sin(300.0 * t),
        "u_q": 20.0 + np.cos(200.0 * t),
        "i_d": 0.3 * np.sin(500.0 * t),
        "i_q": 2.0 + np.sin(70.0 * t),
        "omega_m": w,
        "theta_e": theta,
    }
    rows = [",".join(cols)] + [",".join(f"{c[k]:.17g}" for c in cols.values()) for k in range(n)]
    return "\n".join(rows) + "\n"


LOG = log_csv_text()


# --- corruptions of text: each draws its place and returns the changed lines ---------------------------


@st.composite
def line_edit(draw, lines: list[str]) -> list[str]:
    """Delete, duplicate or garble one line, or insert a line of random text or bytes."""
    lines = list(lines)
    k = draw(st.integers(0, len(lines) - 1))
    kind = draw(st.sampled_from(["delete", "duplicate", "garble", "insert"]))
    if kind == "delete":
        del lines[k]
    elif kind == "duplicate":
        lines.insert(k, lines[k])
    elif kind == "garble":
        line = lines[k]
        a = draw(st.integers(0, len(line)))
        b = draw(st.integers(a, len(line)))
        lines[k] = line[:a] + draw(st.text(max_size=8)) + line[b:]
    else:
        lines.insert(k, draw(st.text(max_size=20)))
    return lines


@st.composite
def number_edit(draw, lines: list[str], others=OTHER_VALUES) -> list[str]:
    """Scale one number by 10^-3..10^3 or put a value of another type in its place."""
    places = [(k, m) for k, line in enumerate(lines) for m in NUMBER.finditer(line.split("#")[0])]
    if not places:
        return lines
    k, m = draw(st.sampled_from(places))
    if draw(st.booleans()):
        factor = 10.0 ** draw(st.floats(-3.0, 3.0))
        new = repr(float(m.group()) * factor)
    else:
        new = draw(st.sampled_from(others))
    lines = list(lines)
    lines[k] = lines[k][: m.start()] + new + lines[k][m.end() :]
    return lines


@st.composite
def corrupted(draw, text: str, edits) -> bytes:
    """``text`` after 1-3 random edits, as bytes; sometimes with random bytes spliced in."""
    lines = text.splitlines()
    for _ in range(draw(st.integers(1, 3))):
        lines = draw(st.one_of(*(edit(lines) for edit in edits))) or [""]
    data = ("\n".join(lines) + "\n").encode("utf-8", "surrogatepass")
    if draw(st.integers(0, 4)) == 0:
        at = draw(st.integers(0, len(data)))
        data = data[:at] + draw(st.binary(min_size=1, max_size=8)) + data[at:]
    return data


# --- drive files ---------------------------------------------------------------------------------------


@FUZZ
@given(data=st.data(), which=st.sampled_from(DRIVE_FILES))
def test_corrupted_drive_file_is_read_or_refused_in_one_line(data, which):
    name, n_phases = which
    text = (PRESET_FOLDER / name).read_text()
    raw = data.draw(corrupted(text, (line_edit, number_edit)))
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "drive.toml"
        path.write_bytes(raw)
        spec = assert_refused_or_read(lambda: drive_spec(path, n_phases=n_phases))
        if spec is not None:  # what a command goes on with is a complete drive of finite numbers
            numbers = [v for t in (spec.motor, spec.ratings, spec.inverter, spec.control) for v in t.values()]
            assert all(math.isfinite(v) for v in numbers) and spec.u_dc_v > 0 and spec.Ts > 0


# --- logs ----------------------------------------------------------------------------------------------


@st.composite
def column_edit(draw, lines: list[str]) -> list[str]:
    """Drop a column (header and rows), or put NaN, inf, text or an empty field into one cell."""
    header = lines[0].split(",")
    j = draw(st.integers(0, len(header) - 1))
    if draw(st.booleans()):
        return [",".join(f for i, f in enumerate(line.split(",")) if i != j) for line in lines]
    k = draw(st.integers(1, len(lines) - 1))
    fields = lines[k].split(",")
    if j < len(fields):
        fields[j] = draw(st.sampled_from(["nan", "inf", "-inf", "", "abc", "1e999", "0x10", "--1"]))
    return lines[:k] + [",".join(fields)] + lines[k + 1 :]


@st.composite
def time_edit(draw, lines: list[str]) -> list[str]:
    """Make time go backwards or stand still: swap or copy two rows' time fields."""
    a, b = sorted(draw(st.lists(st.integers(1, len(lines) - 1), min_size=2, max_size=2, unique=True)))
    rows = [line.split(",") for line in lines]
    if len(rows[a]) and len(rows[b]):
        if draw(st.booleans()):
            rows[a][0], rows[b][0] = rows[b][0], rows[a][0]
        else:
            rows[b][0] = rows[a][0]
    return [",".join(r) for r in rows]


def log_number_edit(lines):
    return number_edit(lines, others=["nan", "inf", "x", "", "1,2", '"1"'])


LOG_EDITS = (line_edit, log_number_edit, column_edit, time_edit)


@FUZZ
@given(raw=corrupted(LOG, LOG_EDITS))
def test_corrupted_log_is_read_or_refused_in_one_line(raw):
    from tuning.identify.log import load_drive_log

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "log.csv"
        path.write_bytes(raw)
        wanted = ("u_d", "u_q", "i_d", "i_q", "omega_m", "theta_e")
        cols = assert_refused_or_read(lambda: read_log(path, ("time",), wanted))
        if cols is not None:
            assert all(np.isfinite(c).all() for c in cols.values()) and (np.diff(cols["time"]) > 0).all()
        log = assert_refused_or_read(lambda: load_drive_log(path, 4))
        if log is not None:
            assert log.n >= 2


@pytest.fixture(scope="module")
def fit_stand_in():
    """``identify``'s fit replaced by a stand-in that ends the command as Ctrl-C would (exit 130): the
    fuzzing is about the checks before the fit, and one fit compiles for minutes."""
    import tuning.identify.pipeline as pipeline

    def accepted(log, options):
        raise KeyboardInterrupt

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(pipeline, "identify", accepted)
        yield


@FUZZ
@given(raw=corrupted(LOG, LOG_EDITS))
def test_identify_command_on_a_corrupted_log(fit_stand_in, raw):
    """``pmsmjax identify``: refused with exit 2, one line on stderr and no output folder, or accepted (the
    stand-in fit: exit 130, the folder made for the lock gone again as it holds nothing)."""
    with tempfile.TemporaryDirectory() as folder:
        log, out = Path(folder) / "log.csv", Path(folder) / "out"
        log.write_bytes(raw)
        stderr = io.StringIO()
        with contextlib.redirect_stderr(stderr):
            status = pmsmjax.cli.main(["identify", str(log), "--pole-pairs", "4", "--out", str(out)])
        lines = stderr.getvalue().splitlines()
        assert status in (2, 130), stderr.getvalue()
        assert len(lines) == 1 and lines[0].startswith(
            "pmsmjax identify: " + ("error" if status == 2 else "in")
        )
        assert not out.exists()


def test_valid_log_reaches_the_fit(fit_stand_in, tmp_path):
    """The uncorrupted log passes every check (so the properties above are not refusing everything)."""
    log = tmp_path / "log.csv"
    log.write_text(LOG)
    assert pmsmjax.cli.main(["identify", str(log), "--pole-pairs", "4", "--out", str(tmp_path / "o")]) == 130
    for name, n_phases in DRIVE_FILES:
        drive_spec(PRESET_FOLDER / name, n_phases=n_phases)
