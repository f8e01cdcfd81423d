"""Smoke test of the multi-phase cost benchmarks (benchmarks/multiphase_cost.py behind bench_six_phase and
bench_five_phase), run as the scripts they are at their quick sizes: every drive is timed, and each ratio
is taken against the three-phase reference with the same bridge and batch."""

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
#: Keys every multi-phase cost report holds (benchmarks/multiphase_cost.py).
REQUIRED_KEYS = ("drives", "duration_s", "batch", "dtype", "machine")


@pytest.mark.slow
@pytest.mark.parametrize("script", ["bench_six_phase", "bench_five_phase"], ids=["six", "five"])
def test_quick_run_reports_every_drive_against_its_reference(script, tmp_path):
    path = tmp_path / "cost.json"
    command = [sys.executable, "-m", f"benchmarks.{script}", "--quick", "--json", str(path)]
    run = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, check=False)
    assert run.returncode == 0, run.stderr[-3000:]
    r = json.loads(path.read_text())
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
    assert all(name in run.stdout for name in drives)  # the printed table names every drive
