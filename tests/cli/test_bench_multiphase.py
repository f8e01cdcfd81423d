"""Smoke test of the multi-phase cost benchmarks (benchmarks/multiphase_cost.py behind bench_six_phase and
bench_five_phase) at their quick sizes: every drive is timed, and each ratio is taken against the
three-phase reference with the same bridge and batch."""

import math

import pytest

from benchmarks import bench_five_phase, bench_six_phase
from benchmarks.multiphase_cost import REQUIRED_KEYS


@pytest.mark.parametrize("bench", [bench_six_phase, bench_five_phase], ids=["six", "five"])
def test_quick_run_reports_every_drive_against_its_reference(bench):
    r = bench.run(quick=True)
    assert set(REQUIRED_KEYS) <= set(r)
    drives = r["drives"]
    batch = r["batch"]
    for reference in ("three-phase", "three-phase switching", f"three-phase x{batch}"):
        assert drives[reference]["vs_three_phase"] == 1.0
    assert drives[f"three-phase x{batch}"]["runs"] == batch
    for name, o in drives.items():
        assert math.isfinite(o["us_per_period"]) and o["us_per_period"] > 0, name
        # the ratio is this drive's cost over its reference's, whichever reference that is
        ref = [
            v
            for v in drives.values()
            if math.isclose(v["us_per_period"], o["us_per_period"] / o["vs_three_phase"])
        ]
        assert ref, name
    assert any(name.endswith(f"x{batch}") and not name.startswith("three") for name in drives)
    table = bench.format_table(r)
    assert all(name in table for name in drives)
