"""Measure the sensorless start from standstill on the book scenario for every observer (issue 14 notes)."""

import jax
import numpy as np

jax.config.update("jax_enable_x64", True)
from pmsmjax import presets  # noqa: E402
from pmsmjax.estimators import OBSERVERS  # noqa: E402
from pmsmjax.frames import wrap_angle  # noqa: E402
from pmsmjax.simulate import simulate  # noqa: E402

RPM = 30 / np.pi
sc = presets.book_scenario()
ref = simulate(presets.book_drive(), sc)
t = np.asarray(ref.t)
w_ref = np.asarray(ref.omega_m) * RPM
print(f"| sensored | - | - | - | {w_ref[t > 0.2].min():.0f} | {w_ref[-1]:.1f} |")
for name in OBSERVERS:
    tr = simulate(presets.sensorless_drive(name, startup=True), sc)
    w = np.asarray(tr.omega_m) * RPM
    err = np.degrees(np.abs(np.asarray(wrap_angle(tr.theta_e_est - tr.theta_e))))
    after = t > 0.031
    sp = np.abs(np.asarray(tr.omega_m_est - tr.omega_m))[after] * RPM
    print(
        f"| {name} | {np.sqrt((err[after] ** 2).mean()):.2f} | {err[after].max():.2f} | {sp.max():.1f} | "
        f"{w[t > 0.2].min():.0f} | {w[-1]:.1f} |"
    )
