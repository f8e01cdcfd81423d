"""A bench capture identified through the command line: the heat run of an imperfect drive (SciPy's
integrators, not the engine; tuning/identify/heat_run_log.py) in four bursts of 100 ms, written as an
instrument writes it (tuning/identify/bench_capture.py): a preamble, semicolons, time in ms, two current
sensors (one in mA), duties in percent with the DC link, an encoder's quadrature count and the speed in
erpm; and the same data as a MATLAB v7.3 file.

``identify --sensor-errors --dead-time`` must meet the heat-run tests' accuracy: offsets within 5 mA, the
gain ratio within 0.2 %, the encoder offset within 0.3 deg, R within 1 % of R / g_a (at 20 degC), L_d and
L_q within 2 % of L / g_a, psi_f within 0.5 %; the MAT file gives the same result.
"""

import json
import math

import numpy as np
import pytest

from pmsmjax.cli import main
from pmsmjax.io.logs import read_log
from tuning.identify.bench_capture import (
    CAPTURE_CONFIG,
    MAT_CONFIG,
    capture_columns,
    write_capture_csv,
    write_capture_mat,
)
from tuning.identify.heat_run_log import DEAD_TIME_V, MOTOR, SENSORS, heat_run_log

G_A = SENSORS["current_gain"][0]
PRIOR = (
    "[motor]\nR = 0.5\nL_d = 0.002\nL_q = 0.003\npsi_f = 0.08\npole_pairs = 4\nJ = 0.001\nB = 0.0001\n"
    '[sensor]\nkind = "encoder"\nlines = 2500\n'
)


@pytest.fixture(scope="module")
def heat_run():
    return heat_run_log(duration_s=120.0, heating_s=120.0, capture_every_s=30.0, capture_s=0.1)


def test_the_capture_file_is_as_an_instrument_writes_it(heat_run, tmp_path):
    path = write_capture_csv(tmp_path / "capture.csv", heat_run)
    lines = path.read_text().splitlines()
    assert lines[0] == "Instrument;Bench logger" and lines[3] == "" and lines[4].startswith("#")
    assert lines[5].startswith("Time [ms];Phase A [A];Ib/mA;Duty A [%]")
    cols = read_log(path, ["Time [ms]", "Encoder [counts]", "Duty A [%]"], time="Time [ms]")
    assert np.sum(np.diff(cols["Time [ms]"]) > 1.0) == 3  # four bursts
    counts = cols["Encoder [counts]"]
    assert np.all(counts == np.floor(counts)) and counts.min() >= 0 and counts.max() < 10_000
    assert 0.0 < cols["Duty A [%]"].min() and cols["Duty A [%]"].max() < 100.0


def _identify(log, config, out, extra=()):
    argv = ["identify", str(log), "--sensor-errors", "--dead-time", "--motor", str(out.parent / "prior.toml"),
            "--config", str(config), "--out", str(out), "--fix", "J=0.001", "--fix", "B=0.0001",
            "--load", "none", "--no-figures", *extra]  # fmt: skip
    assert main(argv) == 0
    return json.loads((out / "params.json").read_text())


def _errors(summary) -> dict:
    """The identified values' errors: offsets in A, the gain ratio and the machine relative, the encoder
    offset in degrees."""
    e, p = summary["sensor_errors"], summary["parameters"]
    ratio = SENSORS["current_gain"][1] / SENSORS["current_gain"][0]
    return {
        "offset_a": [
            o["value"] - t for o, t in zip(e["current_offset_a"], SENSORS["current_offset_a"], strict=True)
        ],
        "gain_ratio": e["current_gain"][1]["value"] / ratio - 1.0,
        "encoder_deg": math.degrees(e["encoder_offset_rad"]["value"] - SENSORS["encoder_offset_rad"]),
        "R": p["R"]["value"] / (MOTOR["R"] / G_A) - 1.0,
        "L_d": p["L_d"]["value"] / (MOTOR["L_d"] / G_A) - 1.0,
        "L_q": p["L_q"]["value"] / (MOTOR["L_q"] / G_A) - 1.0,
        "psi_f": p["psi_f"]["value"] / MOTOR["psi_f"] - 1.0,
        "V_dt": summary["extra_parameters"]["V_dt"]["value"] / DEAD_TIME_V - 1.0,
    }


@pytest.mark.slow
def test_a_bench_capture_csv_and_mat_identify_the_imperfect_drive(heat_run, tmp_path, capsys):
    """Measured: offsets -2.9, +2.1 mA; gain ratio -0.07 %; encoder offset -0.07 deg (whole counts of a
    2500-line encoder); R +0.47 % (at 20 degC), L_d -0.15 %, L_q -0.16 %, psi_f +0.007 %, V_dt -2.7 %; the
    MAT v7.3 file's result equal to the CSV's (the same float64 data)."""
    (tmp_path / "prior.toml").write_text(PRIOR)
    csv = write_capture_csv(tmp_path / "capture.csv", heat_run)
    (tmp_path / "capture.toml").write_text(CAPTURE_CONFIG)
    s = _identify(csv, tmp_path / "capture.toml", tmp_path / "csv", ["--columns", "i_a=Phase A [A]"])
    text = capsys.readouterr().out
    assert "4 captures" in text, text
    err = _errors(s)
    assert all(abs(o) < 0.005 for o in err["offset_a"]), err
    assert abs(err["gain_ratio"]) < 0.002 and abs(err["encoder_deg"]) < 0.3, err
    assert abs(err["R"]) < 0.01 and abs(err["psi_f"]) < 0.005, err
    assert abs(err["L_d"]) < 0.02 and abs(err["L_q"]) < 0.02, err

    mat = write_capture_mat(tmp_path / "capture.mat", heat_run)
    assert mat.read_bytes()[:19] == b"MATLAB 7.3 MAT-file"
    (tmp_path / "mat.toml").write_text(MAT_CONFIG)
    s_mat = _identify(mat, tmp_path / "mat.toml", tmp_path / "mat")
    err_mat = _errors(s_mat)
    for name, value in err.items():
        np.testing.assert_allclose(err_mat[name], value, rtol=1e-6, atol=1e-9, err_msg=name)


def test_the_mat_file_reads_as_the_csv(heat_run, tmp_path):
    """The v7.3 file's datasets are stored transposed (``(1, N)`` for MATLAB's ``N x 1``) and read back as
    columns equal to the CSV's."""
    import h5py

    mat = write_capture_mat(tmp_path / "capture.mat", heat_run)
    with h5py.File(mat, "r") as f:
        assert f["Ia"].shape == (1, heat_run["time"].size)
        assert f["Ia"].attrs["MATLAB_class"] == b"double"
    got = read_log(mat, ["Time_ms", "Ia", "Ib"], time="Time_ms")
    cols = capture_columns(heat_run)
    np.testing.assert_allclose(got["Ia"], cols["Phase A [A]"], rtol=0, atol=0)
    csv = read_log(write_capture_csv(tmp_path / "c.csv", heat_run), ["Ib/mA"], time=None)
    np.testing.assert_allclose(got["Ib"], csv["Ib/mA"], rtol=1e-11)
