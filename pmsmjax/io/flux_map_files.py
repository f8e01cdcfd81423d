"""Flux-map files: read a measured map into a checked [`FluxMapGrid`][pmsmjax.machines.flux_map.FluxMapGrid].

Formats (SI units: A, Wb peak phase flux linkage in the amplitude-invariant dq frame):

- **CSV** with the header ``i_d,i_q,psi_d,psi_q``, one row per grid point, rows in any order (lines
  starting with ``#`` are comments);
  An optional fifth column ``measured`` (1 or 0) marks the grid points a measurement determined; a 0
  point holds a value only so the interpolant has one everywhere (``pmsmjax identify --flux-map`` fills
  the points its log did not reach from their neighbours): do not trust the map there.
  [`read_flux_map_measured`][pmsmjax.io.flux_map_files.read_flux_map_measured] returns the marks; the plant
  uses every point alike;
- **NPZ** or **MAT** (MATLAB) with 1-D axes ``i_d (n_d,)``, ``i_q (n_q,)`` and 2-D ``psi_d``, ``psi_q``
  ``(n_d, n_q)``;
- **NPZ** or **MAT** with complex 2-D grids ``i_s_dq = i_d + j i_q`` and ``psi_s_dq = psi_d + j psi_q``
  (the layout some public machine-design tools write), rows along either axis.

Other tools' layouts (scattered points, SyR-e, inductance tables, motulator) are converted into the same grid
([`pmsmjax.io.flux_map_formats`][pmsmjax.io.flux_map_formats], chosen by ``[motor] flux_map_format`` or by
the file's extension and content); a grid's NaN fluxes are holes, filled and marked not measured.

A careless file (a missing column or array, a grid with holes or uneven steps, NaN, currents in mA) is
refused with one [`ParameterError`][pmsmjax.spec.validation.ParameterError] naming the file and the fix.
"""

import dataclasses
import hashlib
from pathlib import Path

import numpy as np

from pmsmjax.io.flux_map_formats import FORMATS
from pmsmjax.machines.flux_map import FluxMapGrid
from pmsmjax.spec.validation import ParameterError, plain

__all__ = [
    "read_flux_map",
    "read_flux_map_file",
    "read_flux_map_measured",
    "write_flux_map_csv",
    "FluxMapRead",
    "CSV_COLUMNS",
    "MEASURED_COLUMN",
]

CSV_COLUMNS = ("i_d", "i_q", "psi_d", "psi_q")
#: The optional CSV column marking measured (1) and filled (0) grid points.
MEASURED_COLUMN = "measured"
#: A map whose currents reach this far (A) with an incremental inductance below MA_INDUCTANCE_H (H) was
#: written in mA: a real machine with kA currents has flux linkages of volts-seconds, not millivolt-seconds.
MA_CURRENT_A = 1000.0
MA_INDUCTANCE_H = 1e-5


@dataclasses.dataclass(frozen=True, eq=False)
class FluxMapRead:
    """A map file as read: the checked `grid`, its `measured` marks (``(n_d, n_q)`` bool, None when every
    point was measured and the file marks none), the `fmt` it was read as (a key of
    ``pmsmjax.io.flux_map_formats.FORMATS``) and `how`: one line on what was converted or
    filled, empty for a complete grid in pmsmjax's layout."""

    grid: FluxMapGrid
    measured: np.ndarray | None
    fmt: str
    how: str = ""


#: The maps read so far: ``{absolute path: (content hash, FluxMapRead)}``. A map read again (the design
#: rules re-read the drive file's map by its path) is read as it was the first time, in its drive file's
#: ``flux_map_format``, without interpolating it again.
_READ = {}


def read_flux_map(path, fmt: str | None = None) -> FluxMapGrid:
    """Read and check the flux map ``path`` (``.csv``, ``.npz`` or ``.mat``; module docstring) as the
    format `fmt` (``pmsmjax.io.flux_map_formats.FORMATS``; None: by extension and content)."""
    return read_flux_map_file(path, fmt).grid


def read_flux_map_file(path, fmt: str | None = None, name: str = "flux_map_format") -> FluxMapRead:
    """[`read_flux_map`][pmsmjax.io.flux_map_files.read_flux_map] with the measured marks and how the file
    was converted ([`FluxMapRead`][pmsmjax.io.flux_map_files.FluxMapRead]); `name`: how a refusal names
    `fmt`."""
    path = Path(path)
    where = f"flux map {path}"
    if not path.is_file():
        state = "is a folder: give the map file in it" if path.is_dir() else "does not exist: check the path"
        raise ParameterError(f"{where} {state} (relative to the drive file).")
    if fmt is not None and fmt not in FORMATS:
        raise ParameterError(
            f"{name} = {fmt!r} is not a flux-map format: give one of {', '.join(map(repr, FORMATS))} "
            "(or leave it out: the file's extension and content choose)."
        )
    key, stamp = str(path.resolve()), hashlib.blake2b(path.read_bytes(), digest_size=16).digest()
    hit = _READ.get(key)
    if hit is not None and hit[0] == stamp and fmt in (None, hit[1].fmt):
        return hit[1]
    read = _read(path, fmt, where, name)
    _READ[key] = (stamp, read)
    return read


def _read(path: Path, fmt, where: str, name: str) -> FluxMapRead:
    from pmsmjax.io.flux_map_formats import inductance_tables, motulator, syre

    suffix = path.suffix.lower()
    if suffix not in (".csv", ".npz", ".mat"):
        raise ParameterError(f"{where}: unknown format {suffix!r}: give a .csv, .npz or .mat file.")
    marks, how = None, ""
    if suffix == ".csv":
        if fmt is None:
            header = _csv_header(path)
            fmt = "inductance" if inductance_tables.is_inductance_table(header) else "grid"
        if fmt == "points":
            from pmsmjax.io.flux_map_formats.columns import read_csv_columns

            return _points(read_csv_columns(path, CSV_COLUMNS, where), where)
        if fmt == "grid":
            *axes, marks = _read_csv(path, where)
        elif fmt == "inductance":
            *axes, how = inductance_tables.inductance_grid(path, where)
        else:
            raise ParameterError(f'{where}: {name} = "{fmt}" reads .npz or .mat files, not a CSV.')
    else:
        arrays = _load_arrays(path, suffix, where)
        if fmt is None:
            fmt = (
                "syre" if syre.is_syre(arrays)
                else "inductance" if inductance_tables.is_inductance_table(arrays)
                else "motulator" if motulator.is_motulator(arrays) and not {"i_d", "psi_d"} <= arrays.keys()
                else "grid"
            )  # fmt: skip
        if fmt == "points":
            if motulator.is_motulator(arrays):
                i_s, psi_s = motulator.complex_arrays(arrays, where)
                arrays = {"i_d": i_s.real, "i_q": i_s.imag, "psi_d": psi_s.real, "psi_q": psi_s.imag}
            return _points(arrays, where)
        if fmt == "syre":
            *axes, how = syre.syre_grid(arrays, where)
        elif fmt == "inductance":
            *axes, how = inductance_tables.inductance_grid(arrays, where)
        elif fmt == "motulator":
            i_s, psi_s = motulator.complex_arrays(arrays, where)
            axes = motulator.rectangular(i_s, psi_s)
            if axes is None:
                cols = {"i_d": i_s.real, "i_q": i_s.imag, "psi_d": psi_s.real, "psi_q": psi_s.imag}
                read = _points(cols, where)
                return dataclasses.replace(
                    read, fmt="motulator", how="motulator map off a current grid: " + read.how
                )
            how = "motulator map (complex i_s_dq, psi_s_dq)"
        else:
            axes = _grid_arrays(arrays, where)
    i_d, i_q, psi_d, psi_q = (np.asarray(a, dtype=float) for a in axes)
    if np.shape(psi_d) == np.shape(psi_q) == (i_d.size, i_q.size) and not (
        np.all(np.isfinite(psi_d)) and np.all(np.isfinite(psi_q))
    ):
        from pmsmjax.io.flux_map_formats.scattered import fill_holes

        psi_d, psi_q, known = fill_holes(i_d, i_q, psi_d, psi_q, where)
        marks = known if marks is None else marks & known
        holes = (
            f"{int((~known).sum())} of {known.size} grid points were NaN: filled (thin-plate spline), "
            "marked not measured"
        )
        how = f"{how}; {holes}" if how else holes
    _check_units(i_d, i_q, psi_d, psi_q, where)
    return FluxMapRead(FluxMapGrid(i_d, i_q, psi_d, psi_q, source=where), marks, fmt, how)


def _points(arrays: dict, where: str) -> FluxMapRead:
    """Scattered points (``i_d, i_q, psi_d, psi_q`` 1-D, any order) resampled on a grid."""
    from pmsmjax.io.flux_map_formats.scattered import grid_from_points

    missing = [c for c in CSV_COLUMNS if c not in arrays]
    if missing:
        raise ParameterError(
            f"{where} lacks {', '.join(missing)}: scattered points need i_d, i_q (A), psi_d, psi_q (Wb), "
            "one value per point."
        )
    cols = [np.asarray(arrays[c], dtype=float).reshape(-1) for c in CSV_COLUMNS]
    grid, inside = grid_from_points(*cols, where=where)
    _check_units(grid.i_d, grid.i_q, grid.psi_d, grid.psi_q, where)
    how = (
        f"{cols[0].size} scattered points interpolated (thin-plate spline) onto a {grid.i_d.size} x "
        f"{grid.i_q.size} grid; {int((~inside).sum())} grid points outside their hull marked not measured"
    )
    return FluxMapRead(grid, inside, "points", how)


def _csv_header(path: Path) -> list[str]:
    """The names of the CSV's first line that is not a comment (empty for an unreadable file: the reader
    then says why)."""
    try:
        text = path.read_bytes().decode("utf-8-sig")
    except UnicodeDecodeError:
        return []
    for line in text.splitlines():
        if line.strip() and not line.lstrip().startswith("#"):
            return [h.strip() for h in line.split(",")]
    return []


def _read_csv(path: Path, where: str):
    from pmsmjax.io.flux_map_formats.columns import read_csv_columns, rows_to_grid

    hint = (
        f": a CSV flux map is text with the header {','.join(CSV_COLUMNS)}; a binary map is a .npz or .mat "
        "file"
    )
    cols = read_csv_columns(path, CSV_COLUMNS, where, optional=(MEASURED_COLUMN,), binary_hint=hint)
    marks = cols.get(MEASURED_COLUMN)
    if marks is not None and not np.all((marks == 0) | (marks == 1)):
        raise ParameterError(
            f"{where}: the {MEASURED_COLUMN} column holds {plain(marks[(marks != 0) & (marks != 1)][0])}: "
            "give 1 (a measured point) or 0 (a filled one)."
        )
    values = {"psi_d": cols["psi_d"], "psi_q": cols["psi_q"]}
    if marks is not None:
        values["measured"] = marks == 1
    i_d, i_q, grids = rows_to_grid(cols["i_d"], cols["i_q"], values, where, {"measured": bool})
    return i_d, i_q, grids["psi_d"], grids["psi_q"], grids.get("measured")


def read_flux_map_measured(path, fmt: str | None = None) -> np.ndarray | None:
    """``(n_d, n_q)`` bool marks of the map's measured grid points (rows along i_d, as the grid): a CSV's
    ``measured`` column, the filled NaN holes, the grid points outside scattered points' hull; None when the
    file marks none and has no holes (every point measured). The file is read and checked as
    [`read_flux_map`][pmsmjax.io.flux_map_files.read_flux_map]."""
    return read_flux_map_file(path, fmt).measured


def _load_arrays(path: Path, suffix: str, where: str) -> dict:
    try:
        if suffix == ".npz":
            with np.load(path, allow_pickle=False) as data:
                return {k: np.asarray(data[k]) for k in data.files}
        from scipy.io import loadmat

        return {k: np.asarray(v) for k, v in loadmat(path).items() if not k.startswith("__")}
    except Exception as err:  # a corrupt or foreign file: one line, not a traceback
        raise ParameterError(f"{where}: cannot be read as {suffix} ({' '.join(str(err).split())}).") from err


def _grid_arrays(arrays: dict, where: str):
    if {"i_s_dq", "psi_s_dq"} <= arrays.keys():
        return _complex_grid(arrays["i_s_dq"], arrays["psi_s_dq"], where)
    missing = [c for c in CSV_COLUMNS if c not in arrays]
    if missing:
        raise ParameterError(
            f"{where} lacks the array(s) {', '.join(missing)} "
            f"(it holds {', '.join(sorted(arrays)) or 'none'}): "
            "give i_d, i_q (1-D axes, A) and psi_d, psi_q (2-D, Wb, rows along i_d), or complex i_s_dq and "
            "psi_s_dq grids."
        )
    i_d, i_q = (np.asarray(arrays[k], dtype=float).reshape(-1) for k in ("i_d", "i_q"))
    return i_d, i_q, np.asarray(arrays["psi_d"], dtype=float), np.asarray(arrays["psi_q"], dtype=float)


def _complex_grid(i_s, psi_s, where: str):
    i_s, psi_s = np.asarray(i_s), np.asarray(psi_s)
    if i_s.ndim != 2 or i_s.shape != psi_s.shape:
        raise ParameterError(
            f"{where}: i_s_dq {i_s.shape} and psi_s_dq {psi_s.shape} must be 2-D grids of the same shape."
        )
    if np.allclose(i_s.real, i_s.real[:, :1]) and np.allclose(i_s.imag, i_s.imag[:1, :]):
        pass  # rows along i_d
    elif np.allclose(i_s.real, i_s.real[:1, :]) and np.allclose(i_s.imag, i_s.imag[:, :1]):
        i_s, psi_s = i_s.T, psi_s.T
    else:
        raise ParameterError(
            f"{where}: i_s_dq is not a rectangular grid (i_d constant along one axis, i_q along the other): "
            "resample the map on a regular grid."
        )
    return i_s.real[:, 0], i_s.imag[0, :], psi_s.real.astype(float), psi_s.imag.astype(float)


def _check_units(i_d, i_q, psi_d, psi_q, where: str) -> None:
    top = max(np.nanmax(np.abs(i_d)), np.nanmax(np.abs(i_q)))
    if top < MA_CURRENT_A or i_d.size < 2 or np.shape(psi_d)[:1] != (i_d.size,):
        return
    slope = np.nanmedian(np.abs(np.diff(psi_d, axis=0)) / np.diff(i_d)[:, None])
    if slope < MA_INDUCTANCE_H:
        raise ParameterError(
            f"{where}: currents reach {plain(top)} A with an incremental inductance of {slope:.2g} H: "
            "it looks like the currents are in mA: write them in A (divide by 1000)."
        )


def write_flux_map_csv(path, grid: FluxMapGrid, header: str = "", measured=None) -> Path:
    """Write ``grid`` as a flux-map CSV (one row per grid point, full precision), atomically; with
    ``measured`` (``(n_d, n_q)`` bool) the ``measured`` column marks the points (module docstring)."""
    from pmsmjax.io.logs import atomic_write

    D, Q = np.meshgrid(grid.i_d, grid.i_q, indexing="ij")
    columns = [D.ravel(), Q.ravel(), grid.psi_d.ravel(), grid.psi_q.ravel()]
    names = list(CSV_COLUMNS)
    if measured is not None:
        columns.append(np.asarray(measured, dtype=bool).reshape(D.shape).ravel().astype(int))
        names.append(MEASURED_COLUMN)
    rows = np.column_stack(columns)
    lines = [f"# {line}" for line in header.splitlines()] + [",".join(names)]
    lines += [
        ",".join(repr(float(v)) for v in row[:4]) + (f",{int(row[4])}" if len(row) > 4 else "")
        for row in rows
    ]
    return atomic_write(path, lambda f: f.write("\n".join(lines) + "\n"), mode="w")
