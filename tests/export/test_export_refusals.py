"""``pmsmjax export`` refuses what it cannot write in one line, exit 2, before anything is written: a control
method other than the cascaded PI FOC, a drive whose current loop is a flux map's, a drive file for
another machine, a missing gains file or gains of another control, an output folder that cannot be one."""

import pytest

from pmsmjax.cli import main
from pmsmjax.io.drive_files import PRESET_FOLDER


def refused(argv, capsys) -> str:
    """The one line ``pmsmjax export ARGV`` prints; asserts exit status 2."""
    assert main(["export", *map(str, argv)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("pmsmjax export: error: "), err
    return err


@pytest.mark.parametrize(
    "flags, names",
    [
        (["--control", "smc"], ["--control smc", "--motor book", "--control pi"]),
        (["--control", "dtc", "--motor", "servo-400w"], ["--control dtc", "--motor servo-400w"]),
        (["--motor", "saturated-ipm"], ["--motor saturated-ipm", "[motor] flux_map"]),
        (["--motor", PRESET_FOLDER / "six_phase_book.toml"], ["six_phase_book.toml", "n_phases"]),
        (["--gains", "no_such_gains.toml"], ["--gains no_such_gains.toml", "does not exist"]),
    ],
    ids=["control-smc", "control-dtc", "flux-map", "six-phase-file", "missing-gains"],
)
def test_refusals_write_nothing(tmp_path, capsys, monkeypatch, flags, names):
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "out"
    err = refused([*flags, "--out", out], capsys)
    for name in names:
        assert name in err, err
    assert not out.exists()


def test_gains_of_another_control_are_refused(tmp_path, capsys):
    gains = tmp_path / "gains.toml"
    gains.write_text('[gains]\n"controller.speed.c" = 20.0\n"controller.current.kp_d" = 5.0\n')
    out = tmp_path / "out"
    err = refused(["--gains", gains, "--out", out], capsys)
    assert "controller.speed.c" in err and "--gains" in err
    assert not out.exists()


def test_an_output_path_that_is_a_file_is_refused(tmp_path, capsys):
    path = tmp_path / "taken"
    path.write_text("kept")
    err = refused(["--out", path], capsys)
    assert f"--out {path}" in err
    assert path.read_text() == "kept"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["taken"]
