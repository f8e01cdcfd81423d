"""Flux maps in other tools' layouts (pmsmjax/io/flux_map_formats/) read into the same grid.

One analytic saturated map with cross-saturation, of the secant form every layout can hold
(``psi_d = psi_m + L_d(i) i_d``, ``psi_q = L_q(i) i_q``, both inductances falling with both currents), is
written in each layout (pmsmjax's grid with NaN holes, scattered points, SyR-e's half-plane ``.mat`` in its
own axes, inductance tables, motulator's complex arrays on and off a current grid) and read back; each map
is compared with the analytic flux on a fine grid, the difference in % of the flux range (the largest of
``psi_d``'s and ``psi_q``'s spans on the grid).
"""

import numpy as np
import pytest
from scipy.io import savemat

from pmsmjax.io.drive_files import PRESET_FOLDER, drive_spec
from pmsmjax.io.flux_map_files import read_flux_map, read_flux_map_file, write_flux_map_csv
from pmsmjax.machines.flux_map import FluxMapGrid
from pmsmjax.spec.validation import ParameterError

PSI_M, SPAN, N = 0.1, 40.0, 17
AXIS = np.linspace(-SPAN, SPAN, N)


def psi_analytic(i_d, i_q):
    """Secant inductances falling with both currents: ``(psi_d, psi_q)``, Wb, of currents in A."""
    L_d = 8e-3 / np.sqrt(1.0 + (i_d**2 + 0.5 * i_q**2) / 30.0**2)
    L_q = 16e-3 / np.sqrt(1.0 + (i_q**2 + 0.3 * i_d**2) / 20.0**2)
    return PSI_M + L_d * i_d, L_q * i_q


D, Q = np.meshgrid(AXIS, AXIS, indexing="ij")
REFERENCE = FluxMapGrid(AXIS, AXIS, *psi_analytic(D, Q), source="analytic")
FLUX_RANGE = max(np.ptp(REFERENCE.psi_d), np.ptp(REFERENCE.psi_q))


def difference_percent(grid: FluxMapGrid, span: float = SPAN) -> float:
    """Largest |map - analytic| on a 41 x 41 grid over [-span, span]^2 inside the map's, % of the range."""
    d = np.linspace(max(grid.i_d[0], -span), min(grid.i_d[-1], span), 41)
    q = np.linspace(max(grid.i_q[0], -span), min(grid.i_q[-1], span), 41)
    points = np.stack(np.meshgrid(d, q, indexing="ij"), -1)
    psi, _ = grid.flux(points)
    exact = np.stack(psi_analytic(points[..., 0], points[..., 1]), -1)
    return 100.0 * float(np.abs(psi - exact).max()) / FLUX_RANGE


def syre_arrays(half: bool = True):
    """The map in SyR-e's SR axes (d: high inductance, magnet along -q), MATLAB meshgrid layout, SyR-e's
    d currents (pmsmjax's q) >= 0 only when `half`."""
    id_syre = AXIS[AXIS >= 0] if half else AXIS  # pmsmjax i_q
    iq_syre = -AXIS[::-1]  # pmsmjax i_d = -Iq
    Id, Iq = np.meshgrid(id_syre, iq_syre)  # Id along columns, as MATLAB's meshgrid
    psi_d, psi_q = psi_analytic(-Iq, Id)
    return {"Id": Id, "Iq": Iq, "Fd": psi_q, "Fq": -psi_d}


def test_the_reference_grid_is_within_its_interpolation_error():
    assert difference_percent(REFERENCE) < 0.05


def test_nan_holes_are_filled_and_marked(tmp_path):
    psi_d, psi_q = REFERENCE.psi_d.copy(), REFERENCE.psi_q.copy()
    holes = np.zeros_like(psi_d, dtype=bool)
    holes[[3, 8, 12, 16], [5, 8, 2, 16]] = True  # one on the edge, one in the corner
    psi_d[holes], psi_q[holes] = np.nan, np.nan
    np.savez(tmp_path / "holes.npz", i_d=AXIS, i_q=AXIS, psi_d=psi_d, psi_q=psi_q)
    csv = write_flux_map_csv(tmp_path / "holes.csv", REFERENCE)
    text = csv.read_text().splitlines()
    for j, k in np.argwhere(holes):  # rows are written along i_d, then i_q
        row = 1 + j * N + k
        text[row] = ",".join(text[row].split(",")[:2] + ["nan", "nan"])
    csv.write_text("\n".join(text) + "\n")
    for name in ("holes.npz", "holes.csv"):
        read = read_flux_map_file(tmp_path / name)
        np.testing.assert_array_equal(read.measured, ~holes)
        assert read.fmt == "grid" and "4 of 289 grid points were NaN" in read.how
        np.testing.assert_array_equal(read.grid.psi_d[~holes], REFERENCE.psi_d[~holes])
        assert difference_percent(read.grid) < 0.5, name  # 0.28 %: the corner hole, extrapolated


def test_scattered_points_are_interpolated_and_the_hull_marked(tmp_path):
    rng = np.random.default_rng(0)
    points = rng.uniform(-SPAN, SPAN, (400, 2))
    rows = np.column_stack([points, *psi_analytic(points[:, 0], points[:, 1])])
    path = tmp_path / "points.csv"
    path.write_text("i_d,i_q,psi_d,psi_q\n" + "\n".join(",".join(repr(float(x)) for x in r) for r in rows))
    with pytest.raises(ParameterError, match='flux_map_format = "points"'):
        read_flux_map(path)  # never interpolated unless asked
    read = read_flux_map_file(path, "points")
    assert read.fmt == "points" and read.grid.i_d.size == 41
    assert read.measured[20, 20] and not read.measured[0, 0] and not read.measured[-1, -1]
    assert difference_percent(read.grid) < 1.0
    np.savez(tmp_path / "points.npz", i_d=points[:, 0], i_q=points[:, 1], psi_d=rows[:, 2], psi_q=rows[:, 3])
    again = read_flux_map_file(tmp_path / "points.npz", "points")
    np.testing.assert_allclose(again.grid.psi_q, read.grid.psi_q, atol=1e-12)


@pytest.mark.parametrize("layout", ["fdfq_idiq_n256", "motorModel"])
def test_syre_half_plane_in_its_axes_reads_as_the_map(tmp_path, layout):
    arrays = syre_arrays(half=True)
    assert arrays["Id"].min() == 0.0  # half of pmsmjax's q axis
    content = arrays if layout == "fdfq_idiq_n256" else {"motorModel": {"FluxMap_dq": arrays}}
    savemat(tmp_path / f"{layout}.mat", content)
    read = read_flux_map_file(tmp_path / f"{layout}.mat")
    assert read.fmt == "syre" and "SR axes converted" in read.how and "mirrored" in read.how
    np.testing.assert_array_equal(read.grid.i_d, AXIS)
    np.testing.assert_allclose(read.grid.i_q, AXIS, atol=1e-12)
    # the mirrored half: psi_d even, psi_q odd in i_q, and both the analytic map's
    np.testing.assert_allclose(read.grid.psi_d, read.grid.psi_d[:, ::-1], atol=1e-15)
    np.testing.assert_allclose(read.grid.psi_q, -read.grid.psi_q[:, ::-1], atol=1e-15)
    np.testing.assert_allclose(read.grid.psi_d, REFERENCE.psi_d, atol=1e-15)
    np.testing.assert_allclose(read.grid.psi_q, REFERENCE.psi_q, atol=1e-15)
    assert difference_percent(read.grid) < 0.05


def test_syre_full_plane_and_pm_axes(tmp_path):
    savemat(tmp_path / "full.mat", syre_arrays(half=False))
    full = read_flux_map_file(tmp_path / "full.mat", "syre")
    assert "mirrored" not in full.how
    np.testing.assert_allclose(full.grid.psi_q, REFERENCE.psi_q, atol=1e-15)
    Id, Iq = np.meshgrid(AXIS, AXIS)  # SyR-e "PM" axes: pmsmjax's own
    psi_d, psi_q = psi_analytic(Id, Iq)
    savemat(
        tmp_path / "pm.mat", {"Id": Id, "Iq": Iq, "Fd": psi_d, "Fq": psi_q, "dataSet": {"axisType": "PM"}}
    )
    pm = read_flux_map_file(tmp_path / "pm.mat")
    assert "PM axes" in pm.how
    np.testing.assert_allclose(pm.grid.psi_d, REFERENCE.psi_d, atol=1e-15)


def test_inductance_tables_are_secant(tmp_path):
    with np.errstate(invalid="ignore", divide="ignore"):
        L_d, L_q = (REFERENCE.psi_d - PSI_M) / D, REFERENCE.psi_q / Q  # NaN at zero current: any value works
    np.savez(tmp_path / "lut.npz", i_d=AXIS, i_q=AXIS, L_d=L_d, L_q=L_q, psi_m=PSI_M)
    savemat(tmp_path / "lut.mat", {"id": AXIS, "iq": AXIS, "Ld": L_d, "Lq": L_q, "PM": PSI_M})
    rows = np.column_stack([D.ravel(), Q.ravel(), L_d.ravel(), L_q.ravel(), np.full(D.size, PSI_M)])
    (tmp_path / "lut.csv").write_text(
        "i_d,i_q,L_d,L_q,psi_m\n" + "\n".join(",".join(repr(float(x)) for x in r) for r in rows)
    )
    for name in ("lut.npz", "lut.mat", "lut.csv"):
        read = read_flux_map_file(tmp_path / name)
        assert read.fmt == "inductance" and "secant" in read.how, name
        np.testing.assert_allclose(read.grid.psi_d, REFERENCE.psi_d, atol=1e-15, err_msg=name)
        np.testing.assert_allclose(read.grid.psi_q, REFERENCE.psi_q, atol=1e-15, err_msg=name)
    np.savez(tmp_path / "mh.npz", i_d=AXIS, i_q=AXIS, L_d=1e3 * L_d - 20.0, L_q=L_q, psi_m=PSI_M)
    with pytest.raises(ParameterError, match="secant inductance is above 0"):
        read_flux_map(tmp_path / "mh.npz")


def test_motulator_complex_arrays_on_and_off_a_grid(tmp_path):
    np.savez(
        tmp_path / "grid.npz", i_s_dq=(D + 1j * Q).T, psi_s_dq=(REFERENCE.psi_d + 1j * REFERENCE.psi_q).T
    )
    on = read_flux_map_file(tmp_path / "grid.npz")
    assert on.fmt == "motulator" and on.measured is None
    np.testing.assert_array_equal(on.grid.psi_d, REFERENCE.psi_d)
    jitter = np.random.default_rng(1).uniform(-1.0, 1.0, (2, *D.shape))
    i_d, i_q = D + jitter[0], Q + jitter[1]
    psi_d, psi_q = psi_analytic(i_d, i_q)
    np.savez(tmp_path / "off.npz", i_s_dq=i_d + 1j * i_q, psi_s_dq=psi_d + 1j * psi_q)
    off = read_flux_map_file(tmp_path / "off.npz")
    assert off.fmt == "motulator" and "scattered" in off.how
    assert difference_percent(off.grid) < 1.0


def test_every_format_gives_the_same_map_within_its_error(tmp_path):
    """The maxima the guide quotes, one table: each layout's largest difference from the analytic map."""
    savemat(tmp_path / "syre.mat", syre_arrays(half=True))
    with np.errstate(invalid="ignore", divide="ignore"):
        np.savez(tmp_path / "lut.npz", i_d=AXIS, i_q=AXIS, L_d=(REFERENCE.psi_d - PSI_M) / D,
                 L_q=REFERENCE.psi_q / Q, psi_m=PSI_M)  # fmt: skip
    np.savez(tmp_path / "motulator.npz", i_s_dq=D + 1j * Q, psi_s_dq=REFERENCE.psi_d + 1j * REFERENCE.psi_q)
    write_flux_map_csv(tmp_path / "grid.csv", REFERENCE)
    found = {name: difference_percent(read_flux_map(tmp_path / name)) for name in
             ("grid.csv", "syre.mat", "lut.npz", "motulator.npz")}  # fmt: skip
    assert max(found.values()) < 0.05, found
    assert max(found.values()) - min(found.values()) < 1e-9, found  # one grid, one interpolant


def _drive_file(folder, map_name, extra=""):
    text = (PRESET_FOLDER / "saturated_ipm.toml").read_text()
    text = text.replace('flux_map = "saturated_ipm_map.csv"', f'flux_map = "{map_name}"{extra}')
    (folder / "motor.toml").write_text(text)
    return folder / "motor.toml"


def test_a_drive_file_reads_the_preset_map_in_syre_layout_and_as_points(tmp_path):
    preset = drive_spec("saturated-ipm")
    grid = read_flux_map(PRESET_FOLDER / "saturated_ipm_map.csv")
    Id, Iq = np.meshgrid(grid.i_q, -grid.i_d[::-1])  # SyR-e SR axes, the full plane
    Fd, Fq = grid.psi_q[::-1, :], -grid.psi_d[::-1, :]
    savemat(tmp_path / "syre.mat", {"Id": Id, "Iq": Iq, "Fd": Fd, "Fq": Fq, "dataSet": {"axisType": "SR"}})
    syre = drive_spec(str(_drive_file(tmp_path, "syre.mat", '\nflux_map_format = "syre"')))
    for key in ("L_d", "L_q", "psi_f"):
        assert syre.motor[key] == pytest.approx(preset.motor[key], rel=1e-12), key
    assert "SyR-e map" in syre.derived["motor.flux_map"]
    assert syre.ratings["rated_torque_nm"] == pytest.approx(preset.ratings["rated_torque_nm"], rel=1e-9)
    D_, Q_ = np.meshgrid(grid.i_d, grid.i_q, indexing="ij")
    pick = np.random.default_rng(2).choice(D_.size, 600, replace=False)
    rows = np.column_stack([D_.ravel(), Q_.ravel(), grid.psi_d.ravel(), grid.psi_q.ravel()])[pick]
    (tmp_path / "points.csv").write_text(
        "i_d,i_q,psi_d,psi_q\n" + "\n".join(",".join(repr(float(x)) for x in r) for r in rows)
    )
    points = drive_spec(str(_drive_file(tmp_path, "points.csv", '\nflux_map_format = "points"')))
    assert "600 scattered points" in points.derived["motor.flux_map"]
    for key, rel in (("psi_f", 1e-3), ("L_d", 0.02), ("L_q", 0.02)):
        assert points.motor[key] == pytest.approx(preset.motor[key], rel=rel), key


def test_drive_file_format_refusals_are_one_line(tmp_path):
    write_flux_map_csv(tmp_path / "map.csv", REFERENCE)
    cases = {
        '\nflux_map_format = "femm"': "flux_map_format = 'femm' is not a flux-map format",
        '\nflux_map_format = "syre"': 'flux_map_format = "syre" reads .npz or .mat files',
    }
    for extra, match in cases.items():
        with pytest.raises(ParameterError) as info:
            drive_spec(str(_drive_file(tmp_path, "map.csv", extra)))
        assert "\n" not in str(info.value) and match in str(info.value) and "[motor]" in str(info.value)
    text = (
        (PRESET_FOLDER / "saturated_ipm.toml")
        .read_text()
        .replace(
            'flux_map = "saturated_ipm_map.csv"',
            'flux_map_format = "syre"\nL_d = 0.01\nL_q = 0.02\npsi_f = 0.1',
        )
    )
    (tmp_path / "nomap.toml").write_text(text)
    with pytest.raises(ParameterError, match="without a flux_map"):
        drive_spec(str(tmp_path / "nomap.toml"))
