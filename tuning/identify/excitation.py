"""Identification experiments: a drive scenario that makes every motor parameter identifiable.

What each parameter needs from the data (the model is ``u_d = R i_d + L_d di_d/dt - w_e L_q i_q``,
``u_q = R i_q + L_q di_q/dt + w_e (L_d i_d + psi_f)``, ``J dw/dt = T_e - B w - T_L``):

- `L_d`: d-axis current that changes (``L_d di_d/dt``) and is non-zero at speed (``w_e L_d i_d``). With
  i_d = 0 control nothing in the log depends on L_d, so the experiment injects a pseudo-random binary
  sequence (PRBS) on ``id_ref``.
- `L_q`: q-axis current changes and i_q at speed (``w_e L_q i_q`` in u_d); the speed steps provide both.
- `R` against `psi_f`: in ``u_q`` both multiply slowly varying signals (i_q and w_e); they separate when
  i_q changes at a given speed (acceleration and deceleration) and at several speeds.
- `J`: accelerations (speed steps). `B` against a constant load: several constant speeds.

[`identification_scenario`][tuning.identify.excitation.identification_scenario] is a speed-mode scenario (the
drive's own speed PI, so it can be run on a real drive that has one): a staircase of speed steps, including a
reversal, with a PRBS on ``id_ref``. The PRBS clock (default 10 ms) is longer than the electrical time
constant (a few ms) so each level settles, and its amplitude (default 3 A) is a fraction of the current limit.
"""

import numpy as np

from pmsmjax.scenarios import Profile, Scenario
from pmsmjax.spec.validation import ParameterError
from pmsmjax.units import rpm_to_rad_s

__all__ = ["identification_scenario", "prbs"]

#: Default speed staircase, r/min, one level per equal share of the duration (a reversal included so the
#: speed range covers both directions and several constant speeds).
DEFAULT_SPEEDS_RPM = (400.0, 1000.0, 150.0, 700.0, -300.0, 500.0, 1100.0, 250.0)


def prbs(n_bits: int, order: int = 7, seed: int = 1) -> np.ndarray:
    """``(n_bits,)`` values in {-1, +1} from a maximum-length linear-feedback shift register.

    `order` 7 uses the taps x^7 + x^6 + 1 (period 127); `seed` is the non-zero initial register.
    """
    taps = {5: (5, 3), 6: (6, 5), 7: (7, 6), 9: (9, 5), 10: (10, 7)}
    if order not in taps:
        raise ParameterError(f"prbs order must be one of {sorted(taps)}, got {order!r}.")
    if not 0 < seed < 2**order:
        raise ParameterError(f"prbs seed must be in 1..{2**order - 1} (a non-zero register), got {seed}.")
    a, b = taps[order]
    reg, out = seed, np.empty(n_bits)
    for k in range(n_bits):
        bit = ((reg >> (a - 1)) ^ (reg >> (b - 1))) & 1
        reg = ((reg << 1) | bit) & (2**order - 1)
        out[k] = 1.0 if bit else -1.0
    return out


def identification_scenario(
    duration_s: float = 2.0,
    speeds_rpm=DEFAULT_SPEEDS_RPM,
    id_amplitude_a: float = 3.0,
    prbs_clock_s: float = 0.01,
    load_nm: float = 0.0,
    seed: int = 1,
) -> Scenario:
    """A speed-mode scenario for identification: speed staircase plus a PRBS on ``id_ref``.

    **Arguments:**

    - `duration_s`: length, s; the speed levels share it equally.
    - `speeds_rpm`: speed levels, r/min (several values and both signs make B and a load separable).
    - `id_amplitude_a`: PRBS amplitude on ``id_ref``, A (0 disables the injection: L_d then becomes
      unidentifiable). Keep ``sqrt(id^2 + iq^2)`` below the drive's current limit.
    - `prbs_clock_s`: PRBS bit length, s (longer than the electrical time constant L/R).
    - `load_nm`: constant load torque, N m.
    - `seed`: PRBS register seed.
    """
    speeds = np.asarray(speeds_rpm, dtype=float)
    if speeds.ndim != 1 or speeds.size < 2:
        raise ParameterError(f"speeds_rpm needs at least two levels (r/min), got {speeds_rpm!r}.")
    if not duration_s > 0 or not prbs_clock_s > 0:
        raise ParameterError("duration_s and prbs_clock_s must be > 0 (seconds).")
    times = np.arange(speeds.size) * duration_s / speeds.size
    speed_ref = Profile.piecewise(times, rpm_to_rad_s(speeds))
    n_bits = max(1, int(np.ceil(duration_s / prbs_clock_s)))
    bits = prbs(n_bits, seed=seed)
    id_ref = Profile.piecewise(np.arange(n_bits) * prbs_clock_s, id_amplitude_a * bits)
    return Scenario(
        duration_s=duration_s,
        speed_ref=speed_ref,
        load_torque=Profile.constant(load_nm),
        id_ref=id_ref,
    )
