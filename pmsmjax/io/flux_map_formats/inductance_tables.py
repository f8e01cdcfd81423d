"""Inductance tables, as MATLAB/Simulink lookup-table PMSM models take them: ``L_d(i_d, i_q)``,
``L_q(i_d, i_q)`` and the magnet flux ``psi_m``, turned into the flux map
``psi_d = L_d i_d + psi_m``, ``psi_q = L_q i_q``.

**Secant inductances.** The tables are read as secant (apparent) inductances, flux over current at each
point: that is what the two equations above mean, and what a table must hold for them to give the flux.
An incremental (differential) inductance table ``dpsi/di`` is a different quantity: read as secant it gives
a wrong flux wherever the machine saturates (it would have to be integrated instead); such a table is not
read by this format. At ``i_d = 0`` the flux is ``psi_m`` whatever ``L_d`` says there (a secant inductance is
undefined at zero current: any finite value works).

**Layout.** ``.npz`` or ``.mat`` with 1-D axes ``i_d (n_d,)``, ``i_q (n_q,)`` (A), 2-D ``L_d``, ``L_q`` (H,
``(n_d, n_q)``, rows along i_d; a ``(n_q, n_d)`` table of a non-square grid is transposed) and ``psi_m``
(Wb, peak phase flux linkage, one number); MATLAB-style names ``id``, ``iq``, ``Ld``, ``Lq``, ``psim``,
``PM``, ``psi_f``, ``lambda_m`` are accepted for the same arrays. Or a CSV with the columns
``i_d,i_q,L_d,L_q,psi_m``, one row per grid point. The axis convention is pmsmjax's: d along the magnet,
amplitude-invariant dq currents (peak phase amplitude). The names and layout are this format's, not a
verified MathWorks file layout: a table exported from a Simulink model needs its breakpoints and tables
saved under these names.
"""

import numpy as np

from pmsmjax.io.flux_map_formats.columns import read_csv_columns, rows_to_grid
from pmsmjax.spec.validation import ParameterError

__all__ = ["is_inductance_table", "inductance_grid", "ALIASES", "CSV_COLUMNS"]

#: Accepted array names for each quantity (the first is the canonical one).
ALIASES = {
    "i_d": ("i_d", "id", "Id_index", "id_index"),
    "i_q": ("i_q", "iq", "Iq_index", "iq_index"),
    "L_d": ("L_d", "Ld", "Ld_table"),
    "L_q": ("L_q", "Lq", "Lq_table"),
    "psi_m": ("psi_m", "psim", "PM", "psi_f", "lambda_m"),
}
CSV_COLUMNS = ("i_d", "i_q", "L_d", "L_q", "psi_m")


def _pick(arrays: dict, name: str):
    for alias in ALIASES[name]:
        if alias in arrays:
            return np.asarray(arrays[alias], dtype=float)
    return None


def is_inductance_table(arrays_or_header) -> bool:
    """Whether loaded arrays (or a CSV header's names) hold inductance tables: ``L_d`` and ``L_q``."""
    return all(any(a in arrays_or_header for a in ALIASES[n]) for n in ("L_d", "L_q"))


def _from_csv(path, where):
    cols = read_csv_columns(path, CSV_COLUMNS, where)
    i_d, i_q, grids = rows_to_grid(cols["i_d"], cols["i_q"], {k: cols[k] for k in CSV_COLUMNS[2:]}, where)
    return i_d, i_q, grids["L_d"], grids["L_q"], grids["psi_m"]


def _from_arrays(arrays, where):
    got = {name: _pick(arrays, name) for name in ALIASES}
    missing = [name for name, value in got.items() if value is None]
    if missing:
        raise ParameterError(
            f"{where} lacks {', '.join(missing)} (it holds {', '.join(sorted(arrays)) or 'nothing'}): "
            "inductance tables need i_d, i_q (1-D, A), L_d, L_q (2-D, H) and psi_m (Wb)."
        )
    i_d, i_q = got["i_d"].reshape(-1), got["i_q"].reshape(-1)
    tables = []
    for name in ("L_d", "L_q"):
        table = got[name]
        if table.shape != (i_d.size, i_q.size) and table.shape == (i_q.size, i_d.size):
            table = table.T
        if table.shape != (i_d.size, i_q.size):
            raise ParameterError(
                f"{where}: {name} has shape {table.shape}, the axes are {i_d.size} i_d x {i_q.size} i_q "
                "values."
            )
        tables.append(table)
    if got["psi_m"].size != 1:
        raise ParameterError(f"{where}: psi_m must be one number (Wb), got {got['psi_m'].size} values.")
    return i_d, i_q, tables[0], tables[1], float(got["psi_m"].reshape(-1)[0])


def inductance_grid(source, where: str):
    """The flux map of inductance tables (module docstring).

    Args:
        source: the CSV path, or the loaded arrays of an ``.npz``/``.mat`` file.
        where: how messages name the file.

    Returns:
        ``(i_d, i_q, psi_d, psi_q, how)``: axes (A), fluxes ``(n_d, n_q)`` (Wb), one line on the conversion.
    """
    i_d, i_q, L_d, L_q, psi_m = (
        _from_arrays(source, where) if isinstance(source, dict) else _from_csv(source, where)
    )
    for name, table in (("L_d", L_d), ("L_q", L_q)):
        finite = table[np.isfinite(table)]
        if finite.size and finite.min() <= 0:
            raise ParameterError(
                f"{where}: {name} holds {finite.min():.3g} H: a secant inductance is above 0 (H, not mH)."
            )
    D, Q = np.meshgrid(i_d, i_q, indexing="ij")
    psi_d = L_d * D + psi_m
    psi_d[D == 0] = (np.zeros_like(D) + psi_m)[D == 0]  # psi_m at i_d = 0, whatever L_d holds there
    psi_q = L_q * Q
    psi_q[Q == 0] = 0.0
    how = "inductance tables: psi_d = L_d i_d + psi_m, psi_q = L_q i_q (secant inductances)"
    return i_d, i_q, psi_d, psi_q, how
