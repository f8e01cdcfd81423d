"""CSV logs as instruments and firmware tools write them (pmsmjax/io/csv_dialect.py, log_units.py,
log_formats.py, mat_files.py): delimiters, preambles, decimal commas, units in the column names, erpm, the
VESC Tool preset and MATLAB v7.3 files; each refusal one line naming the key and the fix."""

import math

import numpy as np
import pytest

from pmsmjax.io.csv_dialect import CsvDialect, find_layout
from pmsmjax.io.log_formats import reader_options
from pmsmjax.io.log_units import apply_units, split_unit
from pmsmjax.io.logs import column_names, log_rows, read_log
from pmsmjax.io.mat_files import write_mat_v73
from pmsmjax.spec.validation import ParameterError
from tuning.identify.log import load_drive_log


def one_line(err) -> str:
    text = str(err.value)
    assert "\n" not in text
    return text


def dq_rows(n=200, step_ms=0.1):
    t = np.arange(n) * step_ms
    return {
        "time": t,
        "u_d": 2.0 + np.sin(t),
        "u_q": 20.0 + np.cos(0.5 * t),
        "i_d": 0.3 * np.sin(2 * t),
        "i_q": 2.0 + np.sin(0.3 * t),
        "omega_m": np.full(n, 100.0),
    }


def write(path, lines):
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("delimiter", [",", ";", "\t", " "])
def test_preamble_comments_and_each_delimiter(tmp_path, delimiter):
    sep = "  " if delimiter == " " else delimiter
    lines = [f"Instrument{delimiter if delimiter != ' ' else ':'}Scope", "Sample rate" + sep + "10 kHz", "",
             "% exported", "# channels", sep.join(["time", "u_d", "i_q"])]  # fmt: skip
    lines += [sep.join(f"{v:g}" for v in (0.1 * k, k, -k)) for k in range(5)]
    lines.insert(8, "# a comment between rows")
    path = write(tmp_path / "log.csv", lines)
    assert find_layout(path).header_line == 6
    got = read_log(path, ["time", "u_d", "i_q"])
    np.testing.assert_allclose(got["u_d"], np.arange(5.0))
    assert column_names(path) == ["time", "u_d", "i_q"]


def test_trailing_delimiter_as_vesc_tool_writes_it(tmp_path):
    path = write(tmp_path / "log.csv", ["ms_today;erpm;", "1000;500;", "1001;510;"])
    assert find_layout(path).trailing
    np.testing.assert_array_equal(read_log(path, ["ms_today", "erpm"], time="ms_today")["erpm"], [500, 510])
    write(path, ["ms_today;erpm;", "1000;500;", "1001;510"])
    with pytest.raises(
        ParameterError, match="line 3: 2 fields but the header names 2 columns and a delimiter"
    ):
        read_log(path, ["ms_today"], time="ms_today")


def test_decimal_commas_on_request_and_refused_otherwise(tmp_path):
    path = write(tmp_path / "log.csv", ["time;u_d", "0;1", "0,1;1,5", "0,2;2,5"])
    with pytest.raises(ParameterError) as err:
        read_log(path, ["time", "u_d"])
    assert '[log] decimal = ","' in one_line(err) and "line 3" in str(err.value)
    got = read_log(path, ["time", "u_d"], dialect=CsvDialect(decimal=","))
    np.testing.assert_allclose(got["u_d"], [1.0, 1.5, 2.5])
    with pytest.raises(ParameterError) as err:
        read_log(path, ["time"], dialect=CsvDialect(delimiter=",", decimal=","))
    assert "other than the comma" in one_line(err)


def test_a_stated_header_row_and_delimiter(tmp_path):
    """A preamble that itself looks like a header and a row: the header is found at the stated line."""
    path = write(tmp_path / "log.csv", ["a,b", "1,2", "", "time,u_d", "0,1", "1,2"])
    got = read_log(path, ["time", "u_d"], dialect=CsvDialect(header_row=4))
    np.testing.assert_allclose(got["u_d"], [1.0, 2.0])
    with pytest.raises(ParameterError) as err:
        read_log(path, ["time"], dialect=CsvDialect(header_row=3))
    assert "header_row = 3 is blank" in one_line(err)


@pytest.mark.parametrize(
    "name, split",
    [
        ("Time [ms]", ("Time", "ms")),
        ("i_a (A)", ("i_a", "A")),
        ("Ia/mA", ("Ia", "mA")),
        ("omega/rad/s", ("omega", "rad/s")),
        ("Phase A [A]", ("Phase A", "A")),
        ("t [µs]", ("t", "us")),
        ("CH1 [probe]", ("CH1 [probe]", None)),
        ("u_d", ("u_d", None)),
    ],
)
def test_unit_suffixes(name, split):
    assert split_unit(name) == split


def test_units_in_names_reach_si_and_a_contradiction_is_refused(tmp_path):
    cols = dq_rows()
    path = write(tmp_path / "log.csv", ["Time [ms],u_d (V),u_q,I_d/mA,i_q [A],omega_m [rpm]"] + [
        ",".join(f"{v:.17g}" for v in row)
        for row in zip(cols["time"], cols["u_d"], cols["u_q"], 1e3 * cols["i_d"], cols["i_q"],
                       cols["omega_m"], strict=True)
    ])  # fmt: skip
    log = load_drive_log(path, 4, hold="stator")
    np.testing.assert_allclose(log.time, 1e-3 * cols["time"])
    np.testing.assert_allclose(log.i_dq[:, 0], cols["i_d"])
    np.testing.assert_allclose(log.omega_m, cols["omega_m"] * math.pi / 30.0)
    with pytest.raises(ParameterError) as err:
        load_drive_log(path, 4, units={"time": "s"})
    assert "time = 's' contradicts" in one_line(err) and "says ms" in str(err.value)
    write(path, ["time,u_d,u_q,i_d [V],i_q,omega_m", "0,1,1,1,1,1", "1e-4,1,1,1,1,1"])
    with pytest.raises(ParameterError) as err:
        load_drive_log(path, 4)
    assert "'i_d [V]'" in one_line(err) and "not a unit of i_d" in str(err.value)


def test_erpm_is_the_electrical_speed_in_r_per_min():
    c = {"omega_m": np.array([600.0])}
    apply_units(c, {"omega_m": "erpm"}, "log", pole_pairs=5)
    assert c["omega_m"][0] == pytest.approx(600.0 * 2 * math.pi / 60 / 5)
    with pytest.raises(ParameterError) as err:
        apply_units({"omega_m": np.ones(1)}, {"omega_m": "erpm"}, "log")
    assert "pole pairs" in one_line(err)


VESC_HEADER = (  # VESC Tool's realtime log header (vedderb/vesc_tool, vescinterface.cpp, openRtLogFile)
    "ms_today;input_voltage;temp_mos_max;temp_mos_1;temp_mos_2;temp_mos_3;temp_motor;current_motor;"
    "current_in;d_axis_current;q_axis_current;erpm;duty_cycle;amp_hours_used;amp_hours_charged;"
    "watt_hours_used;watt_hours_charged;tachometer;tachometer_abs;encoder_position;fault_code;vesc_id;"
    "d_axis_voltage;q_axis_voltage;"
)


def vesc_log(path, step_ms):
    names = VESC_HEADER.split(";")[:-1]
    rows = []
    for k in range(60):
        row = dict.fromkeys(names, 0.0)
        row |= {"ms_today": 3_600_000 + step_ms * k, "input_voltage": 48.0, "temp_motor": 30.0,
                "d_axis_current": 0.1 * math.sin(k), "q_axis_current": 5.0 + 0.1 * k, "erpm": 7000.0,
                "d_axis_voltage": -1.0, "q_axis_voltage": 12.0 + 0.01 * k}  # fmt: skip
        rows.append(";".join(f"{row[n]:.10g}" for n in names) + ";")
    return write(path, [VESC_HEADER, *rows])


def test_the_vesc_preset_reads_vesc_tools_log(tmp_path):
    dialect, columns, units = reader_options({"format": "vesc"}, {}, {})
    log = load_drive_log(vesc_log(tmp_path / "vesc.csv", 1), 7, columns=columns, units=units, dialect=dialect)
    assert log.time[1] - log.time[0] == pytest.approx(1e-3)
    np.testing.assert_allclose(log.omega_m, 7000.0 * 2 * math.pi / 60 / 7)
    np.testing.assert_allclose(log.i_dq[:, 1], 5.0 + 0.1 * np.arange(60))
    # VESC Tool's own polling rate (tens of Hz) is too slow for identification: refused with the reason.
    with pytest.raises(ParameterError) as err:
        load_drive_log(vesc_log(tmp_path / "slow.csv", 50), 7, columns=columns, units=units, dialect=dialect)
    assert "sampling step 0.05 s" in one_line(err)
    with pytest.raises(ParameterError) as err:
        reader_options({"format": "vesk"}, {}, {})
    assert "known: vesc" in one_line(err)


def test_mat_v73_columns_rows_and_refusals(tmp_path):
    import h5py
    import scipy.io

    t = np.arange(50) * 1e-4
    path = write_mat_v73(tmp_path / "log.mat", {"time": t, "u_d": 2 * t})
    assert path.read_bytes()[:19] == b"MATLAB 7.3 MAT-file" and log_rows(path) == 50
    assert column_names(path) == ["time", "u_d"]
    np.testing.assert_array_equal(read_log(path, ["time", "u_d"])["u_d"], 2 * t)
    # A matrix is stored transposed (MATLAB is column-major) and read back as MATLAB shows it: 50 x 2,
    # refused as a column the way the same matrix saved as v5 is.
    with h5py.File(path, "a") as f:
        f.create_dataset("both", data=np.stack([t, t]))  # HDF5 (2, 50) = MATLAB 50 x 2
        f.create_dataset("name", data=np.frombuffer(b"a\0b\0", np.uint16)).attrs["MATLAB_class"] = b"char"
    scipy.io.savemat(tmp_path / "v5.mat", {"time": t, "both": np.stack([t, t], axis=1)})
    for p in (path, tmp_path / "v5.mat"):
        with pytest.raises(ParameterError, match=r"'both' has shape \(50, 2\)"):
            read_log(p, ["time", "both"])
    assert "name" not in column_names(path)
    (tmp_path / "cut.mat").write_bytes(path.read_bytes()[:700])
    with pytest.raises(ParameterError) as err:
        read_log(tmp_path / "cut.mat", ["time"])
    assert "v7.3" in one_line(err)
