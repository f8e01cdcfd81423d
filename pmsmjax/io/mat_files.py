"""MATLAB ``.mat`` logs, one variable per column: v4 to v7 files through SciPy's ``loadmat``, v7.3 files
(HDF5 with a 512-byte MATLAB header) through ``h5py``.

A v7.3 file stores each variable as an HDF5 dataset in MATLAB's column-major order, so the dataset's
shape is the variable's reversed: a column vector ``N x 1`` is a ``(1, N)`` dataset, a matrix ``N x 3`` a
``(3, N)`` one; [`read_mat`][pmsmjax.io.mat_files.read_mat] transposes every dataset back, so a variable
reads as MATLAB shows it, whichever version saved it. Datasets of a class that is not numeric
(``char``, ``cell``, ``struct``) and the file's internal groups (``#refs#``) are not columns and are left
out; an empty variable (MATLAB writes its dimensions with a ``MATLAB_empty`` mark) reads as empty.

[`write_mat_v73`][pmsmjax.io.mat_files.write_mat_v73] writes columns as MATLAB's ``save -v7.3`` does (the
header, ``MATLAB_class`` marks, ``N x 1`` doubles), for tests and for tools without MATLAB.
"""

import os
import time
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from pmsmjax.spec.validation import ParameterError

__all__ = ["read_mat", "mat_names", "mat_rows", "is_mat_v73", "write_mat_v73", "NUMERIC_CLASSES"]

#: MATLAB classes read as numbers.
NUMERIC_CLASSES = {
    b"double", b"single", b"logical", b"int8", b"uint8", b"int16", b"uint16", b"int32", b"uint32", b"int64",
    b"uint64",
}  # fmt: skip
#: Bytes of the user block a v7.3 file starts with (MATLAB's 128-byte header, padded).
USERBLOCK_BYTES = 512


def is_mat_v73(path: str | os.PathLike) -> bool:
    """Whether the ``.mat`` file at ``path`` is a v7.3 (HDF5) file: its header says so, or it is HDF5."""
    with open(path, "rb") as f:
        head = f.read(128)
    if head.startswith(b"MATLAB 7.3 MAT-file"):
        return True
    import h5py

    try:
        return bool(h5py.is_hdf5(path))
    except Exception:
        return False


def read_mat(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """``{variable: array}`` of a ``.mat`` log (module docstring); a one-line
    [`ParameterError`][pmsmjax.spec.validation.ParameterError] for a file that is neither."""
    path = Path(path)
    if _v73(path):
        return _read_v73(path)
    import scipy.io

    try:
        data = scipy.io.loadmat(path, squeeze_me=True)
    except Exception as err:
        raise ParameterError(
            f"log file {path}: cannot read it as a MATLAB .mat file ({_one_line(err)}); save one variable "
            "per column (save log.mat time u_d u_q, any version from v4 to v7.3)."
        ) from err
    return {k: v for k, v in data.items() if not k.startswith("__")}


def mat_names(path: str | os.PathLike) -> list[str]:
    """The variable names of a ``.mat`` log, without reading the data."""
    path = Path(path)
    if _v73(path):
        return list(_v73_shapes(path))
    import scipy.io

    try:
        return [name for name, _, _ in scipy.io.whosmat(path)]
    except Exception as err:
        raise ParameterError(
            f"log file {path}: cannot read it as a MATLAB .mat file ({_one_line(err)})."
        ) from err


def mat_rows(path: str | os.PathLike) -> int:
    """The element count of the longest variable of a ``.mat`` log, from its header."""
    path = Path(path)
    if _v73(path):
        shapes = _v73_shapes(path).values()
    else:
        import scipy.io

        shapes = [shape for _, shape, _ in scipy.io.whosmat(path)]
    return max((int(np.prod(s, dtype=np.int64)) for s in shapes), default=0)


def _v73(path: Path) -> bool:
    try:
        return is_mat_v73(path)
    except OSError as err:
        raise ParameterError(f"log file {path}: cannot be read ({err.strerror or err}).") from err


def _one_line(err: Exception) -> str:
    return " ".join(str(err).split())


def _numeric(ds) -> bool:
    cls = ds.attrs.get("MATLAB_class", b"double")
    cls = cls.encode() if isinstance(cls, str) else bytes(cls)
    return cls in NUMERIC_CLASSES


def _datasets(f):
    import h5py

    for name, item in f.items():
        if name.startswith("#") or not isinstance(item, h5py.Dataset) or not _numeric(item):
            continue
        yield name, item


def _v73_shapes(path: Path) -> dict[str, tuple]:
    import h5py

    try:
        with h5py.File(path, "r") as f:
            return {
                name: (0,) if ds.attrs.get("MATLAB_empty", 0) else tuple(reversed(ds.shape))
                for name, ds in _datasets(f)
            }
    except OSError as err:
        raise ParameterError(
            f"log file {path}: cannot read it as a MATLAB v7.3 (HDF5) file ({_one_line(err)}); save it again "
            "from MATLAB (save log.mat -v7.3 time u_d u_q) or as v7."
        ) from err


def _read_v73(path: Path) -> dict[str, np.ndarray]:
    import h5py

    try:
        with h5py.File(path, "r") as f:
            out = {}
            for name, ds in _datasets(f):
                if ds.attrs.get("MATLAB_empty", 0):
                    out[name] = np.zeros(0)
                else:
                    out[name] = np.asarray(ds[()]).T  # MATLAB is column-major: the dataset is transposed
            return out
    except OSError as err:
        raise ParameterError(
            f"log file {path}: cannot read it as a MATLAB v7.3 (HDF5) file ({_one_line(err)}); save it again "
            "from MATLAB (save log.mat -v7.3 time u_d u_q) or as v7."
        ) from err


def write_mat_v73(path: str | os.PathLike, columns: Mapping[str, object]) -> Path:
    """Write equally long 1-D `columns` as MATLAB's ``save -v7.3`` writes column vectors: an HDF5 file with
    the 512-byte user block holding MATLAB's header, one ``N x 1`` double per column (a ``(1, N)``
    dataset, column-major) marked ``MATLAB_class = "double"``. Returns ``Path(path)``."""
    import h5py

    path = Path(path)
    stamp = time.strftime("%a %b %d %H:%M:%S %Y", time.gmtime(0))
    text = f"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: {stamp} HDF5 schema 1.00 .".encode()
    header = text.ljust(116, b" ") + b"\x00" * 8 + b"\x00\x02" + b"IM"
    with h5py.File(path, "w", userblock_size=USERBLOCK_BYTES) as f:
        for name, values in columns.items():
            column = np.asarray(values, dtype=np.float64).reshape(-1, 1)  # N x 1, as MATLAB shows it
            ds = f.create_dataset(name, data=column.T)  # stored transposed: (1, N)
            ds.attrs["MATLAB_class"] = np.bytes_(b"double")
    with open(path, "r+b") as f:
        f.write(header)
    return path
