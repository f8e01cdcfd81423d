"""``pmsmjax observe``: an observer run offline on a logged drive (estimate.csv, observe.json, figure).

References: the plant's true angle and speed in a log made by the sensored book drive (0.5 % noise), the
same log written with abc columns through a NumPy inverse Clarke, and refusals that must name the field
and the fix, exit with status 2 and leave no estimate.csv (nor change an existing one).
"""

import functools
import json
import math

import numpy as np
import pytest

from pmsmjax import presets
from pmsmjax.cli import main
from pmsmjax.io.logs import write_csv_atomic
from pmsmjax.recorded.synthetic_logs import drive_log, speed_scenario

SQRT3 = math.sqrt(3.0)


@functools.cache
def log_columns() -> dict:
    """0.2 s of the book drive stepping to 1000 r/min, 10 N m load at 0.1 s, 0.5 % noise."""
    scenario = speed_scenario(1000.0, duration_s=0.2, load_time_s=0.1)
    return drive_log(presets.book_drive(), scenario, noise=0.005, seed=3)


def write_log(path, columns: dict) -> str:
    write_csv_atomic(path, columns)
    return str(path)


def to_abc(alpha, beta):
    """Inverse amplitude-invariant Clarke, written out (the conventions of docs/book_reference.md)."""
    return alpha, -0.5 * alpha + 0.5 * SQRT3 * beta, -0.5 * alpha - 0.5 * SQRT3 * beta


def read_estimate(path) -> dict:
    with open(path) as f:
        header = f.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    return {name: data[:, j] for j, name in enumerate(header)}


def observe(tmp_path, log_path, *extra, observer="smo", out="out"):
    argv = ["observe", log_path, "--motor", "book", "--observer", observer, "--out", str(tmp_path / out)]
    return main([*argv, *extra])


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """The smo run with truth columns (shared by several checks)."""
    tmp = tmp_path_factory.mktemp("observe")
    path = write_log(tmp / "log.csv", log_columns())
    rc = observe(tmp, path, "--truth-columns", "theta_e,omega_m")
    return tmp, rc


def test_writes_the_estimate_the_summary_and_the_figure(run):
    tmp, rc = run
    assert rc == 0
    est = read_estimate(tmp / "out" / "estimate.csv")
    assert list(est) == ["time", "theta_e", "omega_m"]
    cols = log_columns()
    assert np.array_equal(est["time"], cols["time"])
    assert np.all(est["theta_e"] >= -math.pi) and np.all(est["theta_e"] < math.pi)
    # Against the plant's truth (independent of the observer): < 2 electrical degrees RMS after 0.05 s; at
    # steady speed (0.06-0.1 s, before the load step) the speed estimate (mechanical rad/s) unbiased to 1 %
    # and within 3 % RMS of its noise.
    keep = cols["time"] >= 0.05
    err = np.angle(np.exp(1j * (est["theta_e"] - cols["theta_e"])))[keep]
    assert np.degrees(np.sqrt(np.mean(err**2))) < 2.0
    steady = (cols["time"] >= 0.06) & (cols["time"] < 0.1)
    speed_err = (est["omega_m"] - cols["omega_m"])[steady]
    assert abs(speed_err.mean()) < 0.01 * 104.72 and np.sqrt(np.mean(speed_err**2)) < 0.03 * 104.72
    summary = json.loads((tmp / "out" / "observe.json").read_text())
    assert summary["observer"] == "smo" and summary["samples"] == cols["time"].size
    assert summary["Ts_s"] == pytest.approx(1e-4, rel=1e-9)
    errors = summary["errors"]
    assert errors["angle_rms_deg"] == pytest.approx(np.degrees(np.sqrt(np.mean(err**2))), rel=1e-9)
    assert errors["speed_rms_rpm"] > 0 and errors["finite"]
    assert (tmp / "out" / "observe.png").stat().st_size > 10_000


def test_abc_columns_with_a_column_map_give_the_same_estimate(run, tmp_path):
    tmp, _ = run
    cols = log_columns()
    u = to_abc(cols["u_alpha"], cols["u_beta"])
    i = to_abc(cols["i_alpha"], cols["i_beta"])
    renamed = {"t": cols["time"], "Ua": u[0], "Ub": u[1], "Uc": u[2], "Ia": i[0], "Ib": i[1], "Ic": i[2]}
    renamed["speed"] = cols["omega_m"]  # not named as truth: ignored
    path = write_log(tmp_path / "abc.csv", renamed)
    mapping = ["time=t", "u_a=Ua", "u_b=Ub", "u_c=Uc", "i_a=Ia", "i_b=Ib", "i_c=Ic"]
    assert observe(tmp_path, path, "--columns", *mapping, "--no-figures") == 0
    got = read_estimate(tmp_path / "out" / "estimate.csv")
    ref = read_estimate(tmp / "out" / "estimate.csv")
    assert np.allclose(got["theta_e"], ref["theta_e"], atol=1e-9)
    assert "errors" not in json.loads((tmp_path / "out" / "observe.json").read_text())
    assert not (tmp_path / "out" / "observe.png").exists()


def test_every_observer_runs_from_the_command_line(tmp_path):
    path = write_log(tmp_path / "log.csv", log_columns())
    for name in ("smo-pll", "adaptive-smo", "dq-smo", "mras", "ekf"):
        rc = observe(tmp_path, path, "--truth-columns", "theta_e", "--no-figures", observer=name, out=name)
        assert rc == 0
        errors = json.loads((tmp_path / name / "observe.json").read_text())["errors"]
        assert errors["angle_rms_deg"] < 2.0, name
        assert "speed_rms_rpm" not in errors  # only the named truth is scored


def _edit(columns, **changes):
    out = dict(columns)
    for name, value in changes.items():
        if value is None:
            out.pop(name)
        else:
            out[name] = value
    return out


def _bad_logs():
    cols = log_columns()
    nan = cols["i_alpha"].copy()
    nan[17] = np.nan
    shuffled = cols["time"].copy()
    shuffled[[40, 41]] = shuffled[[41, 40]]
    renamed = _edit(cols, i_beta=None)
    renamed["i_bta"] = cols["i_beta"]
    dq = {k: cols[k] for k in ("time", "theta_e")}
    dq.update(u_d=cols["u_alpha"], u_q=cols["u_beta"], i_alpha=cols["i_alpha"], i_beta=cols["i_beta"])
    huge = _edit(cols, u_alpha=cols["u_alpha"] * 1e300)
    return {
        "nan": (_edit(cols, i_alpha=nan), [], "column 'i_alpha' is NaN.*row 17.*fill the gap"),
        "missing": (renamed, [], "i_beta missing.*'i_bta' looks like 'i_beta': map it with i_beta=i_bta\\)$"),
        "unknown truth": (cols, ["--truth-columns", "theta"], "unknown \\['theta'\\].*theta_e"),
        "absent truth": (
            _edit(cols, omega_m=None),
            ["--truth-columns", "omega_m"],
            "missing column.*omega_m",
        ),
        "time order": (_edit(cols, time=shuffled), [], "strictly increasing.*sort the rows"),
        "time in ms": (_edit(cols, time=cols["time"] * 1e3), [], "longer than 0.001 s.*--units time=ms"),
        "dq voltages": (dq, [], "logged in dq.*stator-frame voltages"),
        "map key": (cols, ["--columns", "ialpha=i_alpha"], "unknown canonical name.*'ialpha'.*i_alpha"),
        "observer": (cols, ["--observer", "smo_pll"], "did you mean 'smo-pll'"),
        "option": (cols, ["--option", "bandwidth=100"], "bandwidth do not apply to observer 'smo'"),
        "diverges": (huge, ["--observer", "ekf"], "observer 'ekf' diverged.*nothing written"),
    }


@pytest.mark.parametrize("case", sorted(_bad_logs()))
def test_bad_logs_are_refused_and_nothing_is_written(case, tmp_path, capsys):
    columns, extra, message = _bad_logs()[case]
    path = write_log(tmp_path / "log.csv", columns)
    out = tmp_path / "out"
    out.mkdir()
    (out / "estimate.csv").write_text("previous run\n")
    argv = ["observe", path, "--motor", "book", "--out", str(out)]
    if "--observer" not in extra:
        argv += ["--observer", "smo"]
    assert main(argv + extra) == 2
    err = capsys.readouterr().err
    assert err.startswith("pmsmjax observe: error: ") and len(err.strip().splitlines()) == 1
    assert __import__("re").search(message, err), err
    assert (out / "estimate.csv").read_text() == "previous run\n"
    assert sorted(p.name for p in out.iterdir()) == ["estimate.csv"]


def test_a_flux_map_drive_file_runs_the_map_aware_observer(tmp_path):
    """A log of the sensored saturated-ipm map drive (its own plant, 0.5 % noise): ``observe --motor
    saturated-ipm`` runs the observer on the file's map, as demo does, and holds the angle; with
    ``--observer-model constant`` the file's constant model leaves the map's steady angle error."""
    from pmsmjax.assemble import spec_drive
    from pmsmjax.io.drive_files import drive_spec

    drive = spec_drive(drive_spec("saturated-ipm"), "pi")
    columns = drive_log(
        drive, speed_scenario(2000.0, duration_s=0.3, load_nm=5.0, load_time_s=0.15), noise=0.005
    )
    path = write_log(tmp_path / "map_log.csv", columns)
    errors = {}
    for model in ("map", "constant"):
        argv = ["observe", path, "--motor", "saturated-ipm", "--observer", "flux-observer",
                "--observer-model", model, "--truth-columns", "theta_e,omega_m", "--settle-s", "0.1",
                "--no-figures", "--out", str(tmp_path / model)]  # fmt: skip
        assert main(argv) == 0
        summary = json.loads((tmp_path / model / "observe.json").read_text())
        assert summary["observer_model"] == model
        errors[model] = summary["errors"]["angle_rms_deg"]
    assert errors["map"] < 1.0 < 5.0 < errors["constant"], errors


def test_observer_model_needs_a_flux_map(tmp_path, capsys):
    path = write_log(tmp_path / "log.csv", log_columns())
    assert observe(tmp_path, path, "--observer-model", "map") == 2
    assert "--observer-model applies to a drive file with a flux map" in capsys.readouterr().err
