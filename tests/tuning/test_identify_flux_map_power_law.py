"""The power-law saturation model fitted to a flux-map log (tuning/identify/flux_model_fit.py,
``pmsmjax identify --flux-map --flux-model power-law``):

- the fit's flux inverse (JAX Newton) is the model's (NumPy Newton of pmsmjax.machines.syrm_saturation, and
  the reluctance reference log's own), for both magnet forms;
- on the PM-assisted reluctance machine's staircase, made with the same model (a self-consistency check,
  not an independent test), the coefficients are recovered within 95 % intervals that cover the truth, the
  magnet is found as a flux in series, and the sampled map's error is below the grid fit's; the CLI writes
  them to flux_map.json and a motor.toml that passes the drive file's checks;
- on the saturated IPM's walk (a map not of the model's form) the fit runs and its error is several times
  the grid fit's;
- a pure reluctance machine's log (no magnet) gives the model without one;
- the flags are refused in one line where they do not belong.
"""

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from tuning.identify.log import drive_log_from_columns
from tuning.identify.reluctance_reference_log import SYRM, syrm_flux, syrm_staircase_log

#: The reluctance machine's coefficients in the model's names (x: q, the high-permeance axis).
TRUTH = {"a_x0": 17.4, "a_xx": 373.0, "a_y0": 52.1, "a_yy": 658.0, "a_xy": 1120.0, "psi_f": SYRM["psi_pm"]}


def _visited_error(grid, i_dq, truth):
    """RMS flux error over the visited currents (each 0.25 A cell once) as a share of the flux range."""
    points = np.unique(np.round(i_dq / 0.25).astype(int), axis=0) * 0.25
    true = truth(*points.T)
    err = np.sum((grid.flux(points)[0] - true) ** 2, axis=1) / 2.0
    return float(np.sqrt(np.mean(err))) / float(np.ptp(true, axis=0).max())


def test_the_fits_inverse_is_the_models():
    from pmsmjax.machines.syrm_saturation import PowerLawSaturation
    from tuning.identify.flux_model_fit import _flux_at

    currents = np.array([[0.0, 0.0], [-16.0, 24.0], [3.0, -5.0], [-8.0, 12.0]])
    with jax.enable_x64(True):
        for model in (PowerLawSaturation(psi_f=0.05), PowerLawSaturation(i_f=8.0)):
            p = {k: jnp.asarray(float(v)) for k, v in vars(model).items()}
            psi, newton = _flux_at(p, jnp.asarray(currents))
            expected = np.array([model.flux(*i) for i in currents])
            np.testing.assert_allclose(np.asarray(psi), expected, atol=1e-10)
            assert float(jnp.max(newton)) < 1e-9
    np.testing.assert_allclose(
        np.array([PowerLawSaturation(psi_f=0.05).flux(*i) for i in currents]),
        syrm_flux(SYRM, *currents.T)[0],
        atol=1e-10,
    )


@pytest.mark.slow  # 35 s: the staircase, the grid fit that starts the model's, three model fits
def test_staircase_recovers_the_coefficients_within_their_intervals(tmp_path, capsys):
    from pmsmjax.cli import main
    from pmsmjax.io.drive_files import drive_spec
    from pmsmjax.io.flux_map_files import read_flux_map
    from pmsmjax.io.logs import write_csv_atomic

    raw = syrm_staircase_log(seed=1)
    log = drive_log_from_columns(raw, SYRM["pole_pairs"], hold="stator")
    write_csv_atomic(tmp_path / "log.csv", raw)
    out = tmp_path / "out"
    args = ["identify", str(tmp_path / "log.csv"), "--flux-map", "--flux-model", "power-law"]
    args += ["--pole-pairs", str(SYRM["pole_pairs"]), "--out", str(out), "--no-figures"]
    assert main(args + ["--fix", f"R={SYRM['R']}", "J=0.015", "B=0.005"]) == 0
    assert "power-law model" in capsys.readouterr().out
    drive_spec(str(out / "motor.toml"))  # the sampled map passes the drive file's MTPA check
    model = json.loads((out / "flux_map.json").read_text())["flux_model"]
    assert model["magnet"] == "flux" and model["exponents"] == "paper"
    for name, value in TRUTH.items():
        entry = model["parameters"][name]
        lo, hi = entry["ci95"]
        assert lo <= value <= hi, (name, entry)
        assert entry["value"] == pytest.approx(value, rel=0.03)  # measured: within 0.8 %
    truth = lambda d, q: syrm_flux(SYRM, d, q)[0]  # noqa: E731
    error = _visited_error(read_flux_map(out / "flux_map.csv"), log.i_dq, truth)
    assert error < 0.0004  # measured 0.020 %, the grid fit's 0.078 %


@pytest.mark.slow  # 40 s: the staircase, the grid fit, four model fits
def test_a_pure_reluctance_machine_is_fitted_without_a_magnet():
    from tuning.identify.flux_model_fit import fit_power_law_flux_map

    machine = dict(SYRM, psi_pm=0.0)
    log = drive_log_from_columns(syrm_staircase_log(machine, seed=1), SYRM["pole_pairs"], hold="stator")
    fit = fit_power_law_flux_map(log, SYRM["pole_pairs"], R=SYRM["R"])
    assert fit.magnet == "none"  # the better magnet form's interval covered zero
    assert fit.model.psi_f == 0.0 and fit.model.i_f == 0.0
    for name, value in TRUTH.items():
        if name != "psi_f":
            lo, hi = fit.parameters[name]["ci95"]
            assert lo <= value <= hi, name
    truth = lambda d, q: syrm_flux(machine, d, q)[0]  # noqa: E731
    assert _visited_error(fit.map.grid, log.i_dq, truth) < 0.0004  # measured 0.020 % (grid fit 0.078 %)


@pytest.mark.slow  # 30 s: the grid fit and two model fits
def test_an_ipm_is_not_a_power_law_machine():
    from tuning.identify.flux_model_fit import fit_power_law_flux_map
    from tuning.identify.saturated_reference_log import SATURATED_IPM, flux_map_log, saturated_flux

    ops_d, ops_q = np.array([-12.0, -8.0, -4.0, 0.0, 4.0]), np.arange(-12.0, 12.5, 4.0)
    raw = flux_map_log(SATURATED_IPM, ops_d, ops_q, speed_rpm=1000.0, dwell_s=4e-3, seed=1)
    log = drive_log_from_columns(raw, SATURATED_IPM["pole_pairs"], hold="stator")
    fit = fit_power_law_flux_map(log, SATURATED_IPM["pole_pairs"], step_a=2.0)
    truth = lambda d, q: saturated_flux(SATURATED_IPM, d, q)[0]  # noqa: E731
    model, grid = (_visited_error(g, log.i_dq, truth) for g in (fit.map.grid, fit.grid_fit.grid))
    assert model > 3.0 * grid  # measured 0.55 % against 0.077 %
    assert fit.residual_rms_wb > 2.0 * fit.grid_fit.residual_rms_wb  # the log says so too


@pytest.mark.parametrize(
    "flags, message",
    [
        (["--flux-model", "power-law"], "--flux-model belongs to --flux-map: add --flux-map."),
        (["--flux-map", "--fit-exponents"], "--fit-exponents belongs to --flux-model power-law"),
        (["--flux-map", "--flux-model", "power-law", "--no-q-symmetry"], "symmetric about the d axis"),
    ],
)
def test_flags_refused_where_they_do_not_belong(tmp_path, capsys, flags, message):
    from pmsmjax.cli import main

    (tmp_path / "log.csv").write_text("time,u_d,u_q,i_d,i_q,omega_m\n0,0,0,0,0,0\n")
    args = ["identify", str(tmp_path / "log.csv"), "--pole-pairs", "2", "--out", str(tmp_path / "o")]
    assert main(args + flags) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1
