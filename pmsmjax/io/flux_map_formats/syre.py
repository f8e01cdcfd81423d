"""SyR-e flux maps (MATLAB ``.mat``, e.g. ``fdfq_idiq_n256.mat``) into pmsmjax's axes.

**What the file holds** (verified from the sources): SyR-e writes its direct model as 2-D arrays ``Id``,
``Iq`` (A) and ``Fd``, ``Fq`` (Vs), laid out as MATLAB's ``meshgrid`` (``Id(1,:)`` the d-axis currents,
``Iq(:,1)`` the q-axis ones; SyR-e's own scripts read them with ``interp2(Id, Iq, Fd, ...)``,
``SyR-e/syre_public`` ``syreManipulateMM/mfiles/MMM_plot_scale.m``), at the top level of
``fdfq_idiq_n256.mat`` or in the struct ``motorModel.FluxMap_dq`` (or ``motorModel.fdfq``) of a saved motor
model (motulator reads ``motorModel.FluxMap_dq.Id`` etc.: ``Aalto-Electric-Drives/motulator``,
``motulator/drive/utils/_flux_maps.py``, ``import_syre_data``). Either layout is read, rows along either
array axis; other variables (``T``, loss maps, ``dataSet``) are ignored except ``dataSet.axisType``.

**The axes.** SyR-e designs synchronous reluctance machines in their own convention ("SR" axes): the d axis
is the high-inductance (high-permeance) axis and a PM-assisted rotor's magnet lies along -q. pmsmjax's d
axis is the magnet's (PMSM convention). The conversion, as motulator's ``import_syre_data`` does it:
``i_d = -Iq``, ``i_q = Id``, ``psi_d = -Fq``, ``psi_q = Fd``; a rotation of the frame by 90 degrees, which
keeps the torque ``1.5 p (psi_d i_q - psi_q i_d)``. SyR-e's "PM" axes (surface-PM style: d along the
magnet) need no conversion. Which: ``dataSet.axisType`` ("SR" or "PM") when the file has it; else where
the magnet's flux lies at zero current (``|Fq(0, 0)|`` ten times ``|Fd(0, 0)|`` or more: "SR"; the other way
round: "PM"); else (no zero-current point, no magnet) SyR-e's own rule, ``sum(Id(:,1)) < 0`` (a d current
below zero) means "PM". Assumption: that last rule is taken from a SyR-e script that loads
``fdfq_idiq_n256.mat`` (found by its text in SyR-e's MATLAB sources, its file not pinned), not from a
documented file format.

**Half a q axis.** SyR-e simulates one half of the plane (its ``Id >= 0``: pmsmjax's ``i_q >= 0``). A map
whose q currents are all >= 0 (or all <= 0) is mirrored by the rotor's symmetry about the d axis:
``psi_d(i_d, -i_q) = psi_d(i_d, i_q)`` and ``psi_q(i_d, -i_q) = -psi_q(i_d, i_q)``; the ``i_q = 0`` line is
kept once.
"""

import numpy as np

from pmsmjax.spec.validation import ParameterError

__all__ = ["is_syre", "syre_grid", "mirror_half_q", "SYRE_KEYS"]

SYRE_KEYS = ("Id", "Iq", "Fd", "Fq")
STRUCT_PATHS = (("motorModel", "FluxMap_dq"), ("motorModel", "fdfq"), ("fdfq",), ("FluxMap_dq",))


def _field(value, name):
    """``value.name`` of a struct as ``scipy.io.loadmat`` returns it (a 1x1 structured array), or None."""
    value = np.asarray(value)
    if value.dtype.names and name in value.dtype.names:
        return np.asarray(value.reshape(-1)[0][name])
    return None


def _find(arrays: dict):
    """The ``Id, Iq, Fd, Fq`` arrays and the axis type (or None) of a loaded SyR-e file, or None."""
    axis_type = None
    data_set = arrays.get("dataSet")
    if data_set is not None:
        kind = _field(data_set, "axisType")
        if kind is not None and kind.size:
            axis_type = str(np.asarray(kind).reshape(-1)[0]).strip()
    if all(k in arrays for k in SYRE_KEYS):
        return {k: np.asarray(arrays[k]) for k in SYRE_KEYS}, axis_type
    for path in STRUCT_PATHS:
        node = arrays.get(path[0])
        for name in path[1:]:
            node = None if node is None else _field(node, name)
        if node is not None and all(_field(node, k) is not None for k in SYRE_KEYS):
            return {k: _field(node, k) for k in SYRE_KEYS}, axis_type
    return None


def is_syre(arrays: dict) -> bool:
    """Whether loaded ``.mat`` arrays are a SyR-e map (module docstring)."""
    return _find(arrays) is not None


def _axes(Id, Iq, where):
    """``(id (n,), iq (m,), transpose)`` of SyR-e's meshgrid arrays, rows along either axis."""
    if Id.ndim != 2 or Id.shape != Iq.shape:
        raise ParameterError(f"{where}: SyR-e's Id {Id.shape} and Iq {Iq.shape} must be 2-D grids alike.")
    if np.allclose(Id, Id[:1, :]) and np.allclose(Iq, Iq[:, :1]):  # meshgrid: Id along columns
        return Id[0, :], Iq[:, 0], True
    if np.allclose(Id, Id[:, :1]) and np.allclose(Iq, Iq[:1, :]):
        return Id[:, 0], Iq[0, :], False
    raise ParameterError(
        f"{where}: SyR-e's Id and Iq are not a rectangular grid (Id constant along one axis, Iq along the "
        'other): give the map as scattered points (flux_map_format = "points").'
    )


def _magnet_axes(ids, iqs, Fd, Fq) -> str:
    """ "SR" or "PM" from where the magnet's flux lies at zero current (module docstring); SyR-e's own rule
    for a map without a zero-current point or without a magnet."""
    j, k = int(np.argmin(np.abs(ids))), int(np.argmin(np.abs(iqs)))
    near_zero = abs(ids[j]) <= np.ptp(ids) / 1e6 and abs(iqs[k]) <= np.ptp(iqs) / 1e6
    fd, fq = (abs(float(F[j, k])) for F in (Fd, Fq))
    if near_zero and max(fd, fq) > 10.0 * min(fd, fq) and max(fd, fq) > 0:
        return "PM" if fd > fq else "SR"
    return "PM" if ids.min() < 0 else "SR"  # SyR-e's sum(Id(:,1)) < 0


def mirror_half_q(i_d, i_q, psi_d, psi_q, tolerance: float = 1e-9):
    """Mirror a map whose q currents are all >= 0 or all <= 0 (module docstring); others unchanged.
    Arrays ``(n_d, n_q)`` with rows along i_d, axes increasing. Returns ``(i_d, i_q, psi_d, psi_q,
    mirrored)``."""
    span = float(np.ptp(i_q)) or 1.0
    if i_q[0] >= -tolerance * span:
        keep = slice(1, None) if abs(i_q[0]) <= tolerance * span else slice(None)
        i_q2 = np.concatenate([-i_q[keep][::-1], i_q])
        psi_d2 = np.concatenate([psi_d[:, keep][:, ::-1], psi_d], axis=1)
        psi_q2 = np.concatenate([-psi_q[:, keep][:, ::-1], psi_q], axis=1)
    elif i_q[-1] <= tolerance * span:
        keep = slice(None, -1) if abs(i_q[-1]) <= tolerance * span else slice(None)
        i_q2 = np.concatenate([i_q, -i_q[keep][::-1]])
        psi_d2 = np.concatenate([psi_d, psi_d[:, keep][:, ::-1]], axis=1)
        psi_q2 = np.concatenate([psi_q, -psi_q[:, keep][:, ::-1]], axis=1)
    else:
        return i_d, i_q, psi_d, psi_q, False
    if abs(i_q2[len(i_q2) // 2]) <= tolerance * span:
        i_q2[len(i_q2) // 2] = 0.0  # the kept zero line, exactly
    return i_d, i_q2, psi_d2, psi_q2, True


def syre_grid(arrays: dict, where: str):
    """A SyR-e map in pmsmjax's axes (module docstring).

    Args:
        arrays: the variables of the ``.mat`` file (``scipy.io.loadmat``).
        where: how messages name the file.

    Returns:
        ``(i_d (n_d,), i_q (n_q,), psi_d, psi_q (n_d, n_q), how)``: A, Wb, rows along i_d, axes increasing;
        ``how`` one line saying which axes were converted and whether the q axis was mirrored.
    """
    found = _find(arrays)
    if found is None:
        raise ParameterError(
            f"{where}: not a SyR-e map: it needs Id, Iq, Fd, Fq (at the top level, as fdfq_idiq_n256.mat, or "
            f"in motorModel.FluxMap_dq); it holds {', '.join(sorted(arrays)) or 'nothing'}."
        )
    data, axis_type = found
    Id, Iq, Fd, Fq = (np.asarray(data[k], dtype=float) for k in SYRE_KEYS)
    if not (Fd.shape == Fq.shape == Id.shape):
        raise ParameterError(
            f"{where}: SyR-e's Fd {Fd.shape} and Fq {Fq.shape} must have Id's shape {Id.shape}."
        )
    ids, iqs, transpose = _axes(Id, Iq, where)
    if transpose:  # rows along SyR-e's d axis
        Fd, Fq = Fd.T, Fq.T
    if axis_type is None:
        axis_type = _magnet_axes(ids, iqs, Fd, Fq)
    if axis_type not in ("SR", "PM"):
        raise ParameterError(f"{where}: dataSet.axisType = {axis_type!r}: SyR-e's axes are 'SR' or 'PM'.")
    if axis_type == "SR":  # pmsmjax d = SyR-e -q, pmsmjax q = SyR-e d
        i_d, i_q, psi_d, psi_q = -iqs, ids, -Fq.T, Fd.T
    else:
        i_d, i_q, psi_d, psi_q = ids, iqs, Fd, Fq
    order_d, order_q = np.argsort(i_d), np.argsort(i_q)
    i_d, i_q = i_d[order_d], i_q[order_q]
    psi_d, psi_q = psi_d[np.ix_(order_d, order_q)], psi_q[np.ix_(order_d, order_q)]
    i_d, i_q, psi_d, psi_q, mirrored = mirror_half_q(i_d, i_q, psi_d, psi_q)
    how = (
        "SyR-e map: SR axes converted (i_d = -Iq, i_q = Id, psi_d = -Fq, psi_q = Fd)"
        if axis_type == "SR"
        else "SyR-e map: PM axes, as in pmsmjax"
    )
    if mirrored:
        how += "; q axis mirrored (psi_d even, psi_q odd in i_q)"
    return i_d, i_q, psi_d, psi_q, how
