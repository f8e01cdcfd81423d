"""Peak memory of the CSV log reader against the float64 columns it returns.

Writes a CSV log of ``--rows`` rows (time, u_d, u_q, i_d, i_q, omega_m; 17 significant digits, as
[`write_csv_atomic`][pmsmjax.io.logs.write_csv_atomic] writes them) into a temporary folder, then reads it
with [`read_log`][pmsmjax.io.logs.read_log] in a fresh subprocess and prints the peak resident memory the
read added (``VmHWM`` after the read minus ``VmRSS`` before it, the peak reset through
``/proc/self/clear_refs`` once NumPy is imported) against the returned arrays' bytes. The reader's budget:
at most 5 times the parsed arrays.

Run: ``python -m benchmarks.log_reader_memory [--rows 1000000] [--chunk-lines N]`` (Linux only).
"""

import argparse
import json
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

COLUMNS = ("time", "u_d", "u_q", "i_d", "i_q", "omega_m")
LIMIT = 5.0

CHILD = r"""
import json, sys, time
import numpy as np
from pmsmjax.io import csv_logs, logs

def status(key):
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(key + ":"):
                return int(line.split()[1]) * 1024
try:
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")  # reset VmHWM to the current RSS
    reset = True
except OSError:
    reset = False
chunk = int(sys.argv[3])
if chunk:
    csv_logs.CSV_CHUNK_LINES = chunk
before = status("VmRSS")
t0 = time.perf_counter()
cols = logs.read_log(sys.argv[1], tuple(sys.argv[2].split(",")))
seconds = time.perf_counter() - t0
peak = status("VmHWM")
print(json.dumps({"before": before, "peak": peak, "reset": reset, "seconds": seconds,
                  "nbytes": int(sum(v.nbytes for v in cols.values())), "rows": int(len(cols["time"]))}))
"""


def write_log(path: Path, rows: int) -> None:
    """A CSV log of `rows` rows, written block by block (the writer's own memory stays small)."""
    rng = np.random.default_rng(0)
    with open(path, "w") as f:
        f.write(",".join(COLUMNS) + "\n")
        block = 100_000
        for start in range(0, rows, block):
            k = min(block, rows - start)
            data = rng.normal(size=(k, len(COLUMNS)))
            data[:, 0] = (start + np.arange(k)) * 1e-4
            np.savetxt(f, data, fmt="%.17g", delimiter=",")


def measure(path: Path, chunk_lines: int = 0) -> dict:
    """Run the reader on `path` in a subprocess; returns its figures (bytes, s)."""
    repo = Path(__file__).resolve().parents[1]
    out = subprocess.run(
        [sys.executable, "-c", CHILD, str(path), ",".join(COLUMNS), str(chunk_lines)],
        capture_output=True,
        text=True,
        check=True,
        cwd=repo,
        env={"PYTHONPATH": str(repo), "PATH": "/usr/bin:/bin"},
    )
    return json.loads(out.stdout)


def main(argv=None) -> int:
    """Print the reader's peak memory against the parsed arrays; exit 1 above `LIMIT` times."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rows", type=int, default=1_000_000)
    parser.add_argument("--chunk-lines", type=int, default=0, help="reader chunk (default: the reader's)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "log.csv"
        t0 = time.perf_counter()
        write_log(path, args.rows)
        size = path.stat().st_size
        print(f"machine: {platform.machine()} {platform.processor() or ''}, NumPy {np.__version__}")
        print(
            f"wrote {args.rows:,} rows x {len(COLUMNS)} columns: {size / 1e6:.1f} MB "
            f"({time.perf_counter() - t0:.1f} s)"
        )
        r = measure(path, args.chunk_lines)
    delta = r["peak"] - r["before"]
    ratio = delta / r["nbytes"]
    print(
        f"parsed arrays {r['nbytes'] / 1e6:.1f} MB; reader peak RSS delta {delta / 1e6:.1f} MB "
        f"({ratio:.2f}x the arrays, {delta / size:.2f}x the file; limit {LIMIT:g}x); read in "
        f"{r['seconds']:.2f} s" + ("" if r["reset"] else " (peak not reset: includes start-up)")
    )
    return 0 if ratio <= LIMIT else 1


if __name__ == "__main__":
    sys.exit(main())
