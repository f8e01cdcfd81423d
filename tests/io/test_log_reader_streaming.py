"""The CSV log reader parses in chunks of lines: its columns equal ``numpy.loadtxt`` of the same file for
every chunk size, its row -> file line map holds across blank and comment lines at chunk boundaries, and
a bad row is named by its file line whatever chunk it falls in."""

import numpy as np
import pytest

from pmsmjax.io import csv_logs, logs
from pmsmjax.io.logs import read_log
from pmsmjax.spec.validation import ParameterError

NAMES = ("time", "u_d", "u_q", "i_d")


def write_log(path, rows, extra_lines=None):
    """A CSV log of ``rows`` ((N, 4) floats) with ``extra_lines`` ({position in the data: text}) between
    rows; returns the file's lines."""
    lines = ["# a comment before the header", ",".join(NAMES)]
    extra_lines = extra_lines or {}
    for k, row in enumerate(rows):
        if k in extra_lines:
            lines.append(extra_lines[k])
        lines.append(",".join(f"{x:.17g}" for x in row))
    path.write_text("\n".join(lines) + "\n")
    return lines


@pytest.fixture
def rows():
    rng = np.random.default_rng(3)
    data = rng.normal(size=(23, 4))
    data[:, 0] = np.cumsum(rng.uniform(0.5, 1.5, 23))
    return data


@pytest.mark.parametrize("chunk", [1, 2, 3, 7, 22, 23, 24, 10_000])
def test_chunked_columns_equal_loadtxt(tmp_path, rows, chunk, monkeypatch):
    path = tmp_path / "log.csv"
    write_log(path, rows, {0: "", 5: "# note", 6: "", 21: "#"})
    monkeypatch.setattr(csv_logs, "CSV_CHUNK_LINES", chunk)
    got = read_log(path, NAMES)
    expected = np.loadtxt(path, delimiter=",", skiprows=2, comments="#", ndmin=2)
    assert expected.shape == (23, 4)
    for j, name in enumerate(NAMES):
        assert got[name].dtype == np.float64
        np.testing.assert_array_equal(got[name], expected[:, j])


@pytest.mark.parametrize("chunk", [1, 2, 3, 5, 10_000])
def test_row_lines_across_skipped_lines(tmp_path, rows, chunk):
    path = tmp_path / "log.csv"
    lines = write_log(path, rows, {0: "", 3: "# x", 4: "", 9: "#", 10: "  "})
    raw, row_lines = csv_logs.read_csv_columns(path, chunk_lines=chunk)
    data_lines = [k + 1 for k, s in enumerate(lines[2:], start=2) if s.strip() and not s.startswith("#")]
    assert [row_lines[r] for r in range(len(rows))] == data_lines
    assert len(row_lines) == len(rows)


@pytest.mark.parametrize("chunk", [2, 4, 10_000])
def test_nan_row_named_by_file_line(tmp_path, rows, chunk, monkeypatch):
    path = tmp_path / "log.csv"
    lines = write_log(path, rows, {2: "# gap"})
    bad = lines.index(",".join(f"{x:.17g}" for x in rows[11]))
    fields = lines[bad].split(",")
    lines[bad] = ",".join([fields[0], "", *fields[2:]])
    path.write_text("\n".join(lines) + "\n")
    monkeypatch.setattr(csv_logs, "CSV_CHUNK_LINES", chunk)
    with pytest.raises(ParameterError, match=rf"'u_d' is NaN .* at row 11 \(file line {bad + 1}\)"):
        read_log(path, NAMES)


@pytest.mark.parametrize("chunk", [3, 10_000])
def test_short_row_named_by_file_line(tmp_path, rows, chunk, monkeypatch):
    path = tmp_path / "log.csv"
    lines = write_log(path, rows)
    lines[15] = lines[15].rsplit(",", 1)[0]
    path.write_text("\n".join(lines) + "\n")
    monkeypatch.setattr(csv_logs, "CSV_CHUNK_LINES", chunk)
    with pytest.raises(ParameterError, match=r"line 16: 3 fields but the header names 4 columns"):
        read_log(path, NAMES)


def test_only_wanted_columns_are_parsed_and_unused_ones_named(tmp_path, rows):
    path = tmp_path / "log.csv"
    write_log(path, rows)
    unused = []
    got = read_log(path, ("time", "u_q"), unused=unused)
    assert list(got) == ["time", "u_q"] and unused == ["u_d", "i_d"]
    raw, _ = csv_logs.read_csv_columns(path, ("time", "u_q"))
    assert raw["u_d"] is None and raw["i_d"] is None
    np.testing.assert_array_equal(got["u_q"], rows[:, 2])


def test_missing_column_refused_from_the_header(tmp_path, rows):
    path = tmp_path / "log.csv"
    write_log(path, rows)
    with pytest.raises(ParameterError, match=r"missing column\(s\) omega_m; present: i_d, time, u_d, u_q"):
        read_log(path, ("time", "omega_m"))
    assert logs.column_names(path) == list(NAMES)
