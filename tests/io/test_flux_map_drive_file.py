"""A drive file with ``[motor] flux_map``: the map is read relative to the file, the linear model the
design rules use comes from the map's incremental inductances, every command's drive is the flux-map plant,
and a run that leaves the map's grid says so."""

import json
import shutil
import subprocess
import sys

import numpy as np
import pytest

from pmsmjax.assemble import spec_drive
from pmsmjax.cli import main as pmsmjax
from pmsmjax.io.drive_files import PRESET_FOLDER, drive_spec
from pmsmjax.io.flux_map_files import read_flux_map
from pmsmjax.machines.pmsm_flux_map import PMSMFluxMapdq
from pmsmjax.spec.validation import ParameterError

PRESET = PRESET_FOLDER / "saturated_ipm.toml"
MAP = PRESET_FOLDER / "saturated_ipm_map.csv"


def test_linear_model_is_the_maps_incremental_inductance_at_rated_current():
    spec = drive_spec("saturated-ipm")
    grid = read_flux_map(MAP)
    i_q = spec.ratings["rated_current_a"]
    # central differences of the map's own interpolant at (0, rated i_q); i_d = 0 is a grid node, where the
    # C1 interpolant's second derivative jumps: the difference is good to about h |jump| ~ 1e-6 relative
    h = 1e-3
    psi = lambda i_d, i_q: np.asarray(grid.at(i_d, i_q)[0])
    L_d = (psi(h, i_q)[0] - psi(-h, i_q)[0]) / (2 * h)
    L_q = (psi(0.0, i_q + h)[1] - psi(0.0, i_q - h)[1]) / (2 * h)
    assert spec.motor["L_d"] == pytest.approx(L_d, rel=1e-5)
    assert spec.motor["L_q"] == pytest.approx(L_q, rel=1e-5)
    assert spec.motor["psi_f"] == pytest.approx(psi(0.0, 0.0)[0], rel=1e-9)
    assert {"motor.L_d", "motor.L_q", "motor.psi_f"} <= spec.derived.keys()


def test_every_control_runs_the_flux_map_plant():
    spec = drive_spec("saturated-ipm")
    for control in ("pi", "smc", "pr"):
        assert isinstance(spec_drive(spec, control).machine, PMSMFluxMapdq)


def test_the_map_path_is_relative_to_the_drive_file(tmp_path, monkeypatch):
    folder = tmp_path / "drive"
    folder.mkdir()
    shutil.copy(PRESET, folder / "ipm.toml")
    shutil.copy(MAP, folder / "saturated_ipm_map.csv")
    monkeypatch.chdir(tmp_path)  # the map is found beside the file, not in the working folder
    assert drive_spec("drive/ipm.toml").motor["L_q"] == pytest.approx(
        drive_spec("saturated-ipm").motor["L_q"]
    )


def test_reading_the_file_loads_neither_jax_nor_scipy():
    """The checks on the map (its grid, MTPA table, rated point) run in NumPy: a fresh interpreter reads
    the drive file without loading JAX or SciPy, and derives what this one does, to the bit."""
    code = (
        "import json, sys\nfrom pmsmjax.io.drive_files import drive_spec\n"
        "summary = drive_spec('saturated-ipm').summary()\n"
        "heavy = [m for m in ('jax', 'jaxlib', 'equinox', 'scipy') if m in sys.modules]\n"
        "print(json.dumps({'heavy': heavy, 'summary': summary}))\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["heavy"] == []
    assert out["summary"] == json.loads(json.dumps(drive_spec("saturated-ipm").summary()))


def test_a_missing_map_is_refused_in_one_line(tmp_path):
    (tmp_path / "ipm.toml").write_text(PRESET.read_text())
    with pytest.raises(ParameterError) as info:
        drive_spec(tmp_path / "ipm.toml")
    message = str(info.value)
    assert "\n" not in message and "[motor] flux_map" in message and "does not exist" in message


@pytest.mark.slow
def test_demo_says_when_the_run_leaves_the_grid(tmp_path, capsys):
    # a current limit above the map's 30 A grid: the plant extrapolates, and the summary says so
    assert pmsmjax(["demo", "--motor", "saturated-ipm", "--current-limit", "40", "--out", str(tmp_path),
                    "--no-figures"]) == 0  # fmt: skip
    entry = json.loads((tmp_path / "summary.json").read_text())["flux_map"]
    assert entry["outside_a"] > 5.0 and entry["warning"]
    assert "left the flux map's grid" in capsys.readouterr().out
