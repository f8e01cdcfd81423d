"""motulator's flux maps: complex space vectors ``i_s_dq = i_d + j i_q`` (A) and
``psi_s_dq = psi_d + j psi_q`` (Vs), saved with ``np.savez`` (``.npz``) or ``savemat`` (``.mat``).

**What motulator holds** (verified from its sources, ``Aalto-Electric-Drives/motulator``
``motulator/drive/utils/_sm_flux_maps.py``, class ``MagneticModel``): complex arrays ``i_s_dq`` and
``psi_s_dq`` of the same shape, peak-valued space vectors (amplitude-invariant, as pmsmjax's dq), the PMSM
convention (d along the magnet: its ``import_syre_data`` converts SyR-e's axes to it), and a ``type``:
``"flux_map"`` (currents on a regular grid, ``indexing="ij"``) or ``"current_map"`` (fluxes on the grid,
currents scattered). motulator has no file format of its own: the arrays saved by name are what this
reads.

**Here.** Currents on a rectangular grid (rows along either axis) are read as they are; currents off a grid
(a current map, an irregular map) are resampled on a current grid as scattered points
([`pmsmjax.io.flux_map_formats.scattered`][pmsmjax.io.flux_map_formats.scattered]), the grid points
outside the data's hull marked not measured. Not verified: the keys of motulator's GradNet data sets
(``datasets/*.npz``, which also carry the rotor angle); they are not read.
"""

import numpy as np

from pmsmjax.spec.validation import ParameterError

__all__ = ["is_motulator", "complex_arrays", "rectangular"]

KEYS = ("i_s_dq", "psi_s_dq")


def is_motulator(arrays: dict) -> bool:
    """Whether loaded arrays hold motulator's complex ``i_s_dq`` and ``psi_s_dq``."""
    return all(k in arrays for k in KEYS)


def complex_arrays(arrays: dict, where: str):
    """``(i_s, psi_s)`` complex arrays of the same shape, checked."""
    if not is_motulator(arrays):
        raise ParameterError(
            f"{where}: not a motulator map: it needs complex i_s_dq and psi_s_dq; it holds "
            f"{', '.join(sorted(arrays)) or 'nothing'}."
        )
    i_s, psi_s = np.asarray(arrays["i_s_dq"]), np.asarray(arrays["psi_s_dq"])
    if i_s.shape != psi_s.shape:
        raise ParameterError(
            f"{where}: i_s_dq {i_s.shape} and psi_s_dq {psi_s.shape} must have the same shape."
        )
    return i_s.astype(complex), psi_s.astype(complex)


def rectangular(i_s, psi_s):
    """``(i_d, i_q, psi_d, psi_q)`` when the currents form a rectangular grid (rows along either axis),
    else None."""
    if i_s.ndim != 2 or min(i_s.shape) < 2:
        return None
    if np.allclose(i_s.real, i_s.real[:, :1]) and np.allclose(i_s.imag, i_s.imag[:1, :]):
        pass  # rows along i_d
    elif np.allclose(i_s.real, i_s.real[:1, :]) and np.allclose(i_s.imag, i_s.imag[:, :1]):
        i_s, psi_s = i_s.T, psi_s.T
    else:
        return None
    return i_s.real[:, 0], i_s.imag[0, :], psi_s.real.astype(float), psi_s.imag.astype(float)
