"""Anticogging (pmsmjax/controllers/anticogging.py, tuning/autotune/anticogging.py): the table's periodic
linear interpolation, the FOC's feed-forward, and the table learnt through the closed loop cutting the speed
ripple at 30 r/min of the book drive with cogging and flux harmonics at least tenfold (RMS and
peak-to-peak of the speed error)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from pmsmjax.assemble import with_parts
from pmsmjax.controllers.anticogging import AnticoggingTable
from pmsmjax.machines.harmonics import MagnetHarmonics
from pmsmjax.presets.three_phase import book_drive
from pmsmjax.spec.validation import ParameterError
from tuning.autotune.anticogging import learn_anticogging

FLUX = [[5, 0.0019, 0.4], [7, 0.0009, -1.1]]
COGGING = [[6, 0.045, 0.3], [12, 0.018, -0.8]]


def test_table_interpolates_linearly_and_periodically():
    table = AnticoggingTable(jnp.array([0.0, 1.0, 3.0, -2.0]))
    step = 2 * np.pi / 4
    angles = jnp.array(
        [0.0, 0.5 * step, 1.25 * step, 3.5 * step, 4.0 * step, -0.5 * step, 2 * np.pi * 7 + step]
    )
    want = [0.0, 0.5, 1.5, -1.0, 0.0, -1.0, 1.0]
    np.testing.assert_allclose(np.asarray(jax.vmap(table.current)(angles)), want, atol=1e-12)
    with pytest.raises(ParameterError, match="N >= 2"):
        AnticoggingTable(jnp.array([1.0]))


def test_feed_forward_reaches_the_current_reference():
    drive = book_drive()
    table = AnticoggingTable(jnp.full(8, 0.3))
    with_table = with_parts(drive, {"controller.anticogging": table})
    c = with_table.controller
    from pmsmjax.signals import Estimate

    estimate = Estimate(jnp.asarray(0.4), jnp.asarray(1.0))
    np.testing.assert_allclose(np.asarray(c.feed_forward(jnp.array([0.0, 1.0]), estimate)), [0.0, 1.3])
    assert drive.controller.anticogging is None


@pytest.mark.slow
def test_learnt_table_cuts_the_speed_ripple_tenfold():
    drive = with_parts(book_drive(), {"machine.harmonics": MagnetHarmonics.from_rows(FLUX, COGGING)})
    result = learn_anticogging(drive, max_steps=2)
    assert result.before["peak_to_peak_rpm"] > 1.0  # the cogging does ripple the speed
    assert result.rms_cut > 10.0 and result.peak_to_peak_cut > 10.0, (result.before, result.after)
    # the table is the cogging's: zero mean, about -T_cog / (1.5 p psi_f) in amplitude
    iq = np.asarray(result.table.iq_a)
    assert abs(iq.mean()) < 1e-4 * np.ptp(iq)
    assert 0.5 < np.ptp(iq) / (2 * 0.06 / 1.0962) < 2.0


def test_anticogging_csv_round_trip_and_refusals(tmp_path):
    from pmsmjax.io.anticogging_files import read_anticogging_csv, write_anticogging_csv

    iq = np.array([0.01, -0.02, 0.03, 0.0])
    path = write_anticogging_csv(tmp_path / "anticogging.csv", iq)
    np.testing.assert_array_equal(read_anticogging_csv(path), iq)
    bad = tmp_path / "bad.csv"
    bad.write_text("theta_e_rad,iq_a\n0.0,0.1\n1.0,0.2\n")
    with pytest.raises(ParameterError, match=r"bins 2 pi j / 2"):
        read_anticogging_csv(bad)
    bad.write_text("angle,iq\n0.0,0.1\n")
    with pytest.raises(ParameterError, match="header must be theta_e_rad,iq_a"):
        read_anticogging_csv(bad)


def test_tune_anticogging_refuses_a_drive_without_cogging(tmp_path):
    import subprocess
    import sys

    done = subprocess.run(
        [sys.executable, "-m", "pmsmjax", "tune", "--motor", "book", "--anticogging", "--out", str(tmp_path)],
        capture_output=True,
        text=True,
    )
    assert done.returncode != 0
    assert "has no [harmonics] cogging" in done.stderr and len(done.stderr.strip().splitlines()) == 1
