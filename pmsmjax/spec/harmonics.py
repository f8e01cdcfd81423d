"""The drive file's ``[harmonics]`` table: magnet flux harmonics and cogging torque
([`pmsmjax.machines.harmonics`][pmsmjax.machines.harmonics] has the model), read and checked before JAX
starts. Plain Python.

    [harmonics]   # theta_e: electrical rotor angle, d axis on phase a; orders per electrical revolution
    flux = [[5, 0.0019, 0.4], [7, 0.0009, -1.1]]    # psi_pm,x += A cos(k (theta_e - shift_x) + phi), Wb
    cogging = [[6, 0.045, 0.3], [12, 0.018, -0.8]]  # T_cog = sum A sin(k theta_e + phi), N m

Each row is ``[order, amplitude, phase]``: the order a whole number >= 1 per electrical revolution, the
amplitude >= 0 (Wb for flux, N m for cogging), the phase in rad. Refused, each in one line naming the key,
the row and the fix: a row that is not three numbers, an order that is not a whole number, a flux order of
1 (the fundamental is ``[motor] psi_f``) or a multiple of 3 (triplen: zero-sequence, no current in a star
winding without neutral), an order given twice, a phase beyond ``2 pi`` (degrees), a flux harmonic above
[`MAX_FLUX_SHARE`][pmsmjax.spec.harmonics.MAX_FLUX_SHARE] of ``psi_f`` and a cogging amplitude above the
rated torque (a unit slip: mWb for Wb, N cm for N m), and ``[harmonics]`` on a five- or six-phase motor.
"""

import math

from pmsmjax.spec.plausibility import OVERRIDE
from pmsmjax.spec.validation import ParameterError, plain

__all__ = ["read_harmonics", "MAX_FLUX_SHARE", "MAX_COGGING_SHARE"]

#: A flux harmonic above this share of ``psi_f`` is refused (back-EMF harmonics of PM machines are a few
#: per cent of the fundamental; more is a unit slip or a trapezoidal machine this sinusoidal model is not).
MAX_FLUX_SHARE = 0.2
#: A cogging amplitude above this share of the rated torque is refused (cogging is typically 0.5-5 % of it).
MAX_COGGING_SHARE = 1.0


def _rows(value, key: str, where: str) -> list[tuple[int, float, float]]:
    name = f"{where}: [harmonics] {key}"
    unit = "Wb" if key == "flux" else "N m"
    example = "[[5, 0.0019, 0.4], [7, 0.0009, -1.1]]" if key == "flux" else "[[6, 0.045, 0.3]]"
    if not isinstance(value, list) or not all(isinstance(r, list) for r in value):
        raise ParameterError(
            f"{name} must be a list of [order, amplitude ({unit}), phase (rad)] rows, e.g. {example}; got "
            f"{value!r}."
        )
    rows, seen = [], set()
    for j, row in enumerate(value):
        numeric = all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in row)
        if len(row) != 3 or not numeric or not all(math.isfinite(x) for x in row):
            raise ParameterError(
                f"{name}[{j}] = {row!r}: give three finite numbers [order, amplitude ({unit}), phase (rad)]."
            )
        order, amplitude, phase = row
        if not float(order).is_integer() or order < 1:
            raise ParameterError(
                f"{name}[{j}] order {plain(order)} must be a whole number >= 1 (per electrical revolution)."
            )
        order = int(order)
        if key == "flux" and order == 1:
            raise ParameterError(f"{name}[{j}] order 1 is the fundamental, [motor] psi_f: drop the row.")
        if key == "flux" and order % 3 == 0:
            raise ParameterError(
                f"{name}[{j}] order {order} is triplen: zero-sequence, it drives no current and makes no "
                "torque in a star winding without neutral (phase EMF only, not line): drop the row."
            )
        if order in seen:
            raise ParameterError(f"{name}: order {order} is given twice: give each order once.")
        seen.add(order)
        if amplitude < 0:
            raise ParameterError(
                f"{name}[{j}] amplitude {plain(amplitude)} {unit} must be >= 0: add pi to the phase instead."
            )
        if abs(phase) > 2.0 * math.pi:
            raise ParameterError(
                f"{name}[{j}] phase {plain(phase)} is beyond 2 pi: it looks like degrees: write "
                f"{plain(round(math.radians(phase), 6))} (rad)."
            )
        rows.append((order, float(amplitude), float(phase)))
    return rows


def read_harmonics(values: dict, motor: dict, ratings: dict, where: str, trust: bool = False) -> dict:
    """The ``[harmonics]`` table checked (module docstring): ``{"flux": rows, "cogging": rows}`` with the
    keys the file gives, each row ``(order, amplitude, phase)``; empty without the table.

    Args:
        values: the file's ``[harmonics]`` table (keys checked by the schema).
        motor: the checked ``[motor]`` values (``psi_f``, ``n_phases``).
        ratings: the completed ``[ratings]`` (``rated_torque_nm``).
        where: how messages name the file.
        trust: skip the plausibility limits (``trust_units = true``).
    """
    if not values:
        return {}
    if motor.get("n_phases", 3) != 3:
        raise ParameterError(
            f"{where}: [harmonics] is modelled for three-phase motors; this motor has {motor['n_phases']} "
            "phases: drop [harmonics]."
        )
    out = {key: tuple(_rows(values[key], key, where)) for key in ("flux", "cogging") if key in values}
    if trust:
        return out
    limits = {
        "flux": (MAX_FLUX_SHARE * motor["psi_f"], "Wb", f"{plain(100 * MAX_FLUX_SHARE)} % of psi_f"),
        "cogging": (MAX_COGGING_SHARE * ratings["rated_torque_nm"], "N m", "the rated torque"),
    }
    for key, rows in out.items():
        limit, unit, what = limits[key]
        for order, amplitude, _ in rows:
            if amplitude > limit:
                slip = "mWb for Wb" if key == "flux" else "N cm or mN m for N m"
                raise ParameterError(
                    f"{where}: [harmonics] {key} order {order} amplitude {plain(amplitude)} {unit} is above "
                    f"{what} ({plain(limit)} {unit}): a unit slip ({slip})? {OVERRIDE}."
                )
    return out
