"""A Monte Carlo study's chunk files (tuning/montecarlo/chunk_files.py): a chunk is reused only when it
carries the study's fingerprint and run count, a damaged one is recomputed with a warning naming it, and
load_results refuses a folder without chunks, a damaged chunk or chunks of two studies."""

import numpy as np
import pytest

from pmsmjax.spec.validation import ParameterError
from tuning.montecarlo.chunk_files import load_chunk, load_results


def _chunk(path, fingerprint="abc:0:4", rows=4):
    np.savez(
        path, fingerprint=np.asarray(fingerprint), finite=np.ones(rows, bool), itae=np.arange(rows) * 1.0
    )


def test_a_chunk_is_reused_only_for_its_study_and_size(tmp_path):
    path = tmp_path / "chunk_00000.npz"
    assert load_chunk(path, "abc:0:4", 4) is None  # not there yet
    _chunk(path)
    data = load_chunk(path, "abc:0:4", 4)
    np.testing.assert_array_equal(data["itae"], [0.0, 1.0, 2.0, 3.0])
    assert "fingerprint" not in data
    assert load_chunk(path, "other:0:4", 4) is None  # another study
    assert load_chunk(path, "abc:0:4", 8) is None  # another chunk size


def test_a_damaged_chunk_is_recomputed_with_a_warning_naming_it(tmp_path):
    path = tmp_path / "chunk_00000.npz"
    _chunk(path)
    path.write_bytes(path.read_bytes()[:40])  # truncated, as by a full disk
    with pytest.warns(UserWarning, match="chunk_00000.npz is damaged"):
        assert load_chunk(path, "abc:0:4", 4) is None


def test_load_results_joins_chunks_in_run_order_and_refuses_what_it_cannot_join(tmp_path):
    with pytest.raises(ParameterError, match="no chunk files"):
        load_results(tmp_path)
    chunks = tmp_path / "chunks"
    chunks.mkdir()
    _chunk(chunks / "chunk_00000.npz", "abc:0:4")
    _chunk(chunks / "chunk_00001.npz", "abc:4:4")
    joined = load_results(tmp_path)
    np.testing.assert_array_equal(joined["itae"], [0.0, 1.0, 2.0, 3.0, 0.0, 1.0, 2.0, 3.0])
    _chunk(chunks / "chunk_00002.npz", "xyz:8:4")
    with pytest.raises(ParameterError, match="different studies"):
        load_results(tmp_path)
    (chunks / "chunk_00002.npz").write_bytes(b"not a zip")
    with pytest.raises(ParameterError, match="chunk_00002.npz is damaged"):
        load_results(tmp_path)
