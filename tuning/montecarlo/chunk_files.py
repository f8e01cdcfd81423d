"""A Monte Carlo study's chunk files (``DIR/chunks/chunk_NNNNN.npz``): each holds a chunk of runs' metrics
and records with the study's fingerprint, so that a rerun on the same folder reuses what matches and
recomputes what is missing or damaged, and [`load_results`][tuning.montecarlo.chunk_files.load_results]
reads every run back."""

import warnings
from pathlib import Path

import jax
import numpy as np

from pmsmjax.spec.validation import ParameterError

__all__ = ["load_agreed", "load_chunk", "load_results"]


def load_agreed(path: Path, key: str, rows: int):
    """[`load_chunk`][tuning.montecarlo.chunk_files.load_chunk] on process 0, its decision shared with
    every process (they must all take part in computing a missing chunk). Only process 0 reads, writes and
    summarises; the others get ``{}`` for a chunk that process 0 has."""
    data = load_chunk(path, key, rows) if jax.process_index() == 0 else None
    if jax.process_count() == 1:
        return data
    from jax.experimental import multihost_utils

    have = bool(multihost_utils.broadcast_one_to_all(np.asarray(data is not None)))
    return (data if data is not None else {}) if have else None


def load_chunk(path: Path, key: str, rows: int):
    """A chunk file's arrays if it exists and carries ``key`` (study fingerprint, first run and run count
    of the chunk) and ``rows`` runs, else None."""
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as f:
            if str(f["fingerprint"]) != key or f["finite"].shape[0] != rows:
                return None
            return {k: f[k] for k in f.files if k != "fingerprint"}
    except Exception as err:  # noqa: BLE001 (a truncated zip raises BadZipFile, EOFError, zlib.error, ...)
        # Atomic writes never leave a half chunk, so this is an outside change (a full disk when copied,
        # a truncated transfer): the runs are recomputed and the file rewritten.
        warnings.warn(
            f"{path} is damaged ({type(err).__name__}: {' '.join(str(err).split())[:80]}): computing its "
            "runs again and rewriting it",
            stacklevel=2,
        )
        return None


def load_results(out_dir) -> dict:
    """Every run's metrics and decimated record from a study folder's chunk files, in run order:
    ``{name: (n,) or (n, N / decimate) array}`` (for analyses beyond summary.json)."""
    paths = sorted((Path(out_dir) / "chunks").glob("chunk_*.npz"))
    if not paths:
        raise ParameterError(f"no chunk files in {Path(out_dir) / 'chunks'}: run the study first.")
    parts = []
    for path in paths:
        try:
            with np.load(path, allow_pickle=False) as f:
                parts.append({k: f[k] for k in f.files})
        except Exception as err:  # noqa: BLE001 (BadZipFile, EOFError, zlib.error, ...)
            raise ParameterError(
                f"{path} is damaged ({type(err).__name__}): rerun the study on {out_dir} to compute its "
                "runs again."
            ) from err
    if len({str(p.pop("fingerprint")).split(":")[0] for p in parts}) != 1:
        raise ParameterError(f"{out_dir} holds chunks of different studies: use one folder per study.")
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
