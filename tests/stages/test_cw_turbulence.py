"""D_L and epsilon (methods 1 and 2) on cw line-of-sight scans with the Lorentzian probe.

Synthetic scans of the virtual cw lidar of Banakh et al. (1999) (lambda = 10.6 um,
a0 = 7.5 cm, phi = 30 deg, T = 7 s, 140 spectra per scan; cwproc.sim.cw) at h = 50 m:
Z_R = lambda R^2/(2 pi a0^2) = 3.0 m at R = 100 m, azimuth step 2.57 deg (dy = 3.9 m),
lags up to 9 deg. The turbulence has sigma_V^2 = 1 m2 s-2 and L_V = 500 m (Banakh et
al. (1999), eq. 17), so that the inertial-range A-functions hold (lags < 3 %, probe
half width < 1 % of L_V) and epsilon = 1.331 sigma_V^3 / L_V = 2.66e-3 m2 s-3
(Banakh et al. (1999), eq. 19). mu = U/V_s = 5/77.7 = 0.06: methods 1 and 2 must agree.

Numbers obtained (40 scans, one block, seed 2): with the first-round probe (uncut
Lorentzian, sweep averaging) epsilon read -2 %; with the cut Banakh Lorentzian, no
sweep averaging (Banakh et al. (1999), eq. 15) and the probe-passed variance it reads
0.93 of the truth (heterodyne centroids). Homodyne (|V_r|) centroids read +81 % at
U = 5 m/s when the folded values near the zero crossings of V_r entered D_L; with
those rays left out (structure.homodyne_radial_velocity, about half the pairs kept)
1.00 of the truth.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import xarray as xr
from hypothesis import given, settings
from hypothesis import strategies as st

from cwproc.physics import exact_lag
from cwproc.physics.dissipation import epsilon_from_integral_scale
from cwproc.physics.probe_variance import passed_variance
from cwproc.physics.transfer import CWProbe
from cwproc.sim.cw import CWLidar, simulate_cw_scans
from cwproc.stages import epsilon, qc, structure, vad
from cwproc.stages.epsilon.flags import FLAG_NOISE_PREDICTED

HEIGHT = 50.0
SIGMA2 = 1.0
OUTER_SCALE = 500.0
WIND_SPEED = 5.0
DIRECTION = 200.0
N_SCANS = 40
TRUE_EPSILON = float(epsilon_from_integral_scale(SIGMA2, OUTER_SCALE, "exponential"))


def _simulate(homodyne: bool, seed: int) -> tuple[xr.Dataset, np.ndarray, CWLidar]:
    lidar = dataclasses.replace(CWLidar(), homodyne=homodyne)
    ds, truth = simulate_cw_scans(
        np.random.default_rng(seed),
        lidar,
        heights_m=np.array([HEIGHT]),
        wind_speed=np.array([WIND_SPEED]),
        wind_direction_deg=DIRECTION,
        sigma2=np.array([SIGMA2]),
        outer_scale_m=np.array([OUTER_SCALE]),
        n_scans=N_SCANS,
        start=np.datetime64("2020-06-01T12:00"),
    )
    return ds, truth, lidar


def _retrieve(ds: xr.Dataset, lidar: CWLidar, tmp_path) -> tuple[xr.Dataset, xr.Dataset]:
    screened = qc.screen_radial_velocity(ds, snr_min=0.008, outlier_threshold=4.0)
    wind = vad.fit_vad(screened, min_rays=20, max_gap_deg=60.0, reference_direction_deg=DIRECTION)
    sf = structure.azimuth_structure_function(screened, wind, n_scans=N_SCANS, max_lag_deg=9.0)
    probe = CWProbe(lidar.z_r_coefficient, lidar.wavelength_m, lidar.beam_radius_m)
    turb = epsilon.estimate_epsilon(
        sf,
        probe=probe,
        lag_number=3,
        model="inertial",
        table_options={"cache_dir": str(tmp_path)},
    )
    return sf, turb


@pytest.fixture(scope="module")
def heterodyne():
    return _simulate(homodyne=False, seed=2)


@pytest.mark.slow
def test_structure_function_of_cw_scans(heterodyne, tmp_path):
    ds, _, lidar = heterodyne
    sf, _ = _retrieve(ds, lidar, tmp_path)
    d = sf["structure_function"].isel(time=0, height=0).values
    assert sf.sizes["lag"] == 3  # 9 deg / 2.57 deg
    assert np.all(np.isfinite(d)) and np.all(np.diff(d) > 0)  # grows with the lag
    # D_L(l) - D_L(1) ~ eps^(2/3) (8/3)((l dy)^(2/3) - dy^(2/3)) within 35 % (probe 3 m << dy)
    dy = np.deg2rad(360.0 / 140) * HEIGHT / np.tan(np.deg2rad(30.0))
    model = TRUE_EPSILON ** (2 / 3) * 8 / 3 * ((3 * dy) ** (2 / 3) - dy ** (2 / 3))
    assert d[2] - d[0] == pytest.approx(model, rel=0.35)


@pytest.mark.slow
def test_epsilon_from_cw_centroid_scans_within_20_percent(heterodyne, tmp_path):
    ds, _, lidar = heterodyne
    _, turb = _retrieve(ds, lidar, tmp_path)
    # three lags leave one degree of freedom for the noise intercept: it may be not
    # significant (flag 32, no prediction for a cw lidar), nothing else is flagged
    assert int(turb["turbulence_flag"].values.ravel()[0]) & ~FLAG_NOISE_PREDICTED == 0
    for name in ("epsilon", "epsilon_method1", "epsilon_fit"):
        assert float(turb[name].values.ravel()[0]) == pytest.approx(TRUE_EPSILON, rel=0.2), name


@pytest.mark.slow
def test_epsilon_from_exact_probe_averaged_velocities_within_20_percent(heterodyne, tmp_path):
    ds, truth, lidar = heterodyne
    exact = ds.assign(radial_velocity=(("ray", "range"), truth))
    _, turb = _retrieve(exact, lidar, tmp_path)
    for name in ("epsilon", "epsilon_method1"):
        assert float(turb[name].values.ravel()[0]) == pytest.approx(TRUE_EPSILON, rel=0.2), name


@pytest.mark.slow
def test_epsilon_from_homodyne_cw_scans_within_20_percent(heterodyne, tmp_path):
    """Homodyne (|V_r| only): rays near the zero crossings of S . <V>_N are left out.

    Without the rule (structure.homodyne_radial_velocity) eps read +81 % here.
    """
    ds, _, lidar = _simulate(homodyne=True, seed=2)
    sf, turb = _retrieve(ds, lidar, tmp_path)
    assert float(turb["epsilon"].values.ravel()[0]) == pytest.approx(TRUE_EPSILON, rel=0.2)
    # |S . <V>_N| = 4.33 |sin(theta - 200)| m/s must exceed 1 m/s + 3 sigma', sigma' the
    # spread of the probe-averaged V_r about the fit (0.8-0.95 m/s here): |sin| > 0.78-0.89,
    # 30-43 % of the azimuths, and fewer of the pairs; the heterodyne scans keep every
    # azimuth but the peaks below 1 m/s
    het_sf, _ = _retrieve(heterodyne[0], lidar, tmp_path)
    kept = sf["n_pairs"].values.ravel()[0] / het_sf["n_pairs"].values.ravel()[0]
    assert 0.15 < kept < 0.45


@pytest.mark.slow
def test_seed000_probe_exact_model_recovers_eps_variance_and_scale(tmp_path):
    """Exact eq-4 data of the seed-000 cw probe at h = 300, 500 m (L_V = 300, 333 m).

    The data are the exact B_D model (``exact_lag.exact_lag_model``, Banakh et al. (1999),
    eqs. 15-17) with white noise sigma_e = 0.05 m/s and the variance of V'_L about the
    10-scan VAD fit. The probe (half width 113-275 m) passes only 44 % and 29 % of
    sigma_V^2; with the inertial averaging loss instead, sigma_V^2 came out 1.9-2.5
    times too large, L_V too large and eps 36-45 % low on the cw simulation. Exact data
    must be inverted to within the interpolation error of the L grid.
    """
    from cwproc.physics.spectra import variance_from

    probe = CWProbe(wavelength_m=10.6e-6, beam_radius_m=0.075)
    heights = np.array([300.0, 500.0])
    big_l = np.array([300.0, 333.0])
    u = np.array([9.14, 9.78])
    noise = 0.05
    sigma2 = np.array([1.11, 1.02]) ** 2
    eps = epsilon_from_integral_scale(sigma2, big_l, "exponential")
    dtheta = 360.0 / 140
    rng_m = heights / np.sin(np.deg2rad(30.0))
    d = np.empty((2, 3))
    var_raw = np.empty(2)
    for i in range(2):
        lm = exact_lag.exact_lag_model(probe, rng_m[i], 30.0, dtheta, 3, "exponential")
        k = np.argmin(np.abs(np.log(lm.scales / big_l[i])))
        big_l[i] = lm.scales[k]  # on the grid: no interpolation error in the data
        d[i] = sigma2[i] * lm.structure[k] + 2 * noise**2
        var_raw[i] = sigma2[i] * (lm.passed[k] - lm.removed[k] / 10) + noise**2
        assert lm.passed[k] == pytest.approx([0.44, 0.29][i], abs=0.02)
    eps = epsilon_from_integral_scale(sigma2, big_l, "exponential")
    sf = xr.Dataset(
        {
            "structure_function": (("time", "height", "lag"), d[None]),
            "n_pairs": (("time", "height", "lag"), np.full((1, 2, 3), 1000)),
            "radial_velocity_variance": (("time", "height"), var_raw[None]),
            "wind_speed": (("time", "height"), u[None]),
            "azimuth_step": ("time", [dtheta]),
            "scan_period": ("time", [7.0]),
            "n_scans": ("time", [10]),
        },
        coords={
            "time": [np.datetime64("2024-01-01T00:00", "ns")],
            "height": heights,
            "range": ("height", rng_m),
            "lag": [1, 2, 3],
            "elevation": ("time", [30.0]),
        },
    )
    options = {
        "cache_dir": str(tmp_path),
        "height_range_m": (250.0, 600.0),
        "outer_scale_range_m": (50.0, 1500.0),
        "mu_max": 0.5,
    }
    out = epsilon.estimate_epsilon(
        sf, probe=probe, lag_number=3, model="exponential", table_options=options
    )
    assert out["integral_scale"].attrs["exact_cw_model_cells"] == 2
    np.testing.assert_allclose(out["epsilon"].values[0], eps, rtol=0.01)
    np.testing.assert_allclose(
        out["velocity_variance"].values[0], variance_from(eps, big_l, "exponential"), rtol=0.01
    )
    np.testing.assert_allclose(out["integral_scale"].values[0], big_l, rtol=0.01)
    np.testing.assert_allclose(out["noise_std"].values[0], noise, rtol=0.02)
    np.testing.assert_allclose(out["structure_function_model"].values[0], d, rtol=1e-3)


@pytest.mark.slow
def test_exact_cw_model_agrees_with_the_spectral_a_functions(tmp_path):
    """Two independent routes to D_L of the seed-000 cw probe agree.

    ``exact_lag_model`` integrates the correlation tensor over both beams (Banakh et al.
    (1999), eq. 15); the A-table integrates the 2-D spectrum with the probe's transfer
    functions at the transverse spacing of the probe centre (Smalikho (2020), eqs.
    15-20). They differ only by the spacing varying along a long probe (1.4-3.8 % of
    A_2 for a 270 m probe), and the probe-passed variances by the quadratures.
    """
    from cwproc.physics.spectra import variance_per_eps23
    from cwproc.tables.atable import get_a_table

    probe = CWProbe(wavelength_m=10.6e-6, beam_radius_m=0.075)
    dtheta = 360.0 / 140
    table = get_a_table(
        probe,
        phi_deg=30.0,
        delta_theta_deg=dtheta,
        n_lags=3,
        model="exponential",
        cache_dir=str(tmp_path),
        height_range_m=(40.0, 600.0),
        outer_scale_range_m=(50.0, 1500.0),
        mu_max=0.5,
    )
    for h, big_l in ((50.0, 133.0), (300.0, 300.0), (500.0, 333.0)):
        r = h / np.sin(np.deg2rad(30.0))
        lm = exact_lag.exact_lag_model(probe, r, 30.0, dtheta, 3, "exponential")
        exact = np.array([np.interp(np.log(big_l), np.log(lm.scales), c) for c in lm.structure.T])
        exact *= variance_per_eps23("exponential", big_l)  # per eps^(2/3), as A_2 / 1
        _, a2 = table.evaluate(np.arange(1.0, 4.0), np.full(3, h), np.zeros(3), np.full(3, big_l))
        assert np.asarray(a2) == pytest.approx(exact, rel=0.05), h
        dy = np.deg2rad(dtheta) * probe.centre_range(r) * np.cos(np.deg2rad(30.0))
        through = passed_variance(probe, [dy], [r], "exponential", [big_l])[0, 0]
        passed = lm.interpolate("passed", np.array(big_l)) * variance_per_eps23(
            "exponential", big_l
        )
        assert through == pytest.approx(passed, rel=0.02), h


def test_vad_removed_variance_equals_the_simulators_trace_of_the_hat_matrix():
    """tr(H B_D)/M of the seed-000 scan (M = 140) from the full circulant row of the sim.

    ``montecarlo.height_model`` computes it independently as the DFT modes 0 and +-1
    of the whole first row of B_D (its own fine quadrature for lag 0); the stage's
    ``vad_removed_variance`` takes B_D(0) from ``passed_variance`` and the other lags
    from its own Lorentzian quadrature. They agree within 0.13 % (tested 0.5 %).
    """
    from cwproc.physics.spectra import variance_per_eps23
    from cwproc.sim.montecarlo import FACTOR_SCALES, height_model

    probe = CWProbe(wavelength_m=10.6e-6, beam_radius_m=0.075)
    lidar = CWLidar(homodyne=False)  # seed 000: M = 140, phi = 30 deg
    scales = FACTOR_SCALES[8:18:3]  # 60-5000 m
    for h in (50.0, 500.0):
        rng_m = np.array([h / np.sin(np.deg2rad(30.0))])
        dy = np.deg2rad(360.0 / 140) * probe.centre_range(rng_m) * np.cos(np.deg2rad(30.0))
        passed = passed_variance(probe, dy, rng_m, "exponential", scales)
        removed = exact_lag.vad_removed_variance(
            probe, rng_m, 30.0, 140, "exponential", scales, passed
        )[0]
        full = np.array([variance_per_eps23("exponential", x) for x in scales])
        exact = height_model(lidar, h, 3).projected[8:18:3] / 140
        assert removed / full == pytest.approx(exact, rel=0.005)


def test_vad_removed_variance_of_uncorrelated_rays_is_three_rays_worth():
    """Rays far apart against L_V: the 3-parameter sine fit removes 3/M of the variance."""
    probe = CWProbe(wavelength_m=10.6e-6, beam_radius_m=0.075)
    rng_m = np.array([100.0])
    passed = np.array([[2.0]])
    removed = exact_lag.vad_removed_variance(
        probe, rng_m, 30.0, 24, "exponential", np.array([0.5]), passed
    )
    assert removed[0, 0] == pytest.approx(3.0 * 2.0 / 24, rel=1e-3)


@pytest.mark.parametrize("noise", [0.0, 0.04])
def test_shape_fit_recovers_level_outer_scale_and_noise_between_grid_nodes(noise):
    """D_L = sigma^2 d(l; L) + 2 sigma_e^2 of the 270 m probe (h = 500 m), L off the grid.

    The L grid is 8 % wide; the parabola in log L and the interpolated model must bring
    L and sigma^2 to within 1 %, and sigma_e to within 5 % (Banakh et al. (1999),
    eqs. 15-17; Smalikho (2020), eq. 4).
    """
    probe = CWProbe(wavelength_m=10.6e-6, beam_radius_m=0.075)
    lm = exact_lag.exact_lag_model(probe, 1000.0, 30.0, 360.0 / 140, 3, "exponential")
    fine = np.geomspace(250.0, 450.0, 41)  # a finer grid gives the truth
    truth = exact_lag.exact_lag_model(probe, 1000.0, 30.0, 360.0 / 140, 3, "exponential", fine)
    k = int(np.argmin(np.abs(np.log(fine / 333.0))))
    assert not np.any(np.isclose(lm.scales, fine[k], rtol=1e-3))  # between the nodes
    d = 1.04 * truth.structure[k] + 2 * noise**2
    s2, big_l, nv = exact_lag.fit_correlation_shape(
        d[None], lm.structure, lm.scales, noise=noise > 0
    )
    assert big_l[0] == pytest.approx(fine[k], rel=0.01)
    assert s2[0] == pytest.approx(1.04, rel=0.01)
    assert np.sqrt(nv[0]) == pytest.approx(noise, rel=0.05, abs=1e-9)
    # fewer than two valid lags: no estimate
    s2, big_l, _ = exact_lag.fit_correlation_shape(
        d[None], lm.structure, lm.scales, np.array([[True, False, False]])
    )
    assert np.isnan(s2[0]) and np.isnan(big_l[0])


@settings(max_examples=30, deadline=None)
@given(
    sigma2=st.floats(min_value=0.05, max_value=4.0),
    log_scale=st.floats(min_value=np.log(30.0), max_value=np.log(3000.0)),
    noise=st.floats(min_value=0.0, max_value=0.15),
    height=st.sampled_from([50.0, 300.0]),
)
def test_exact_cw_fit_returns_eps_of_any_model_structure_function(sigma2, log_scale, noise, height):
    """Model data of any level, outer scale and noise give back eps = c sigma^3 / L.

    Within 3 %: the L grid is 8 % wide and the model is interpolated between nodes; where
    the probe is short against L (h = 50 m, L of kilometres) only eps is determined, and
    it must still come back.
    """
    probe = CWProbe(wavelength_m=10.6e-6, beam_radius_m=0.075)
    lm = exact_lag.exact_lag_model_cached(probe, 2.0 * height, 30.0, 360.0 / 140, 3, "exponential")
    shape = np.array([np.interp(log_scale, np.log(lm.scales), c) for c in lm.structure.T])
    d = sigma2 * shape + 2 * noise**2
    s2, big_l, nv = exact_lag.fit_correlation_shape(d[None], lm.structure, lm.scales, noise=True)
    c = 1.331
    truth = c * sigma2**1.5 / np.exp(log_scale)
    assert c * s2[0] ** 1.5 / big_l[0] == pytest.approx(truth, rel=0.03)
    assert np.sqrt(nv[0]) <= noise + 0.02 * np.sqrt(sigma2)


def test_running_nanmedian_skips_gaps_and_follows_the_order():
    values = np.array([1.0, np.nan, 3.0, 100.0, 5.0])
    got = exact_lag.running_nanmedian(values, np.arange(5), 3)
    np.testing.assert_allclose(got, [1.0, 2.0, 51.5, 5.0, 52.5])
    perm = np.array([3, 0, 4, 1, 2])  # the same sequence, stored out of order
    np.testing.assert_allclose(exact_lag.running_nanmedian(values[perm], perm, 3), got[perm])


def _exact_blocks(probe, sigma2, big_l, noise, dtheta=360.0 / 140):
    """Structure-function datasets of blocks at h = 300 m from the exact model."""
    rng_m = 600.0
    lm = exact_lag.exact_lag_model(probe, rng_m, 30.0, dtheta, 3, "exponential")
    k = np.argmin(np.abs(np.log(lm.scales / big_l)))
    d = sigma2[:, None] * lm.structure[k][None, :] + 2 * noise[:, None] ** 2
    var = sigma2 * (lm.passed[k] - lm.removed[k] / 10) + noise**2
    n = sigma2.size
    sf = xr.Dataset(
        {
            "structure_function": (("time", "height", "lag"), d[:, None, :]),
            "n_pairs": (("time", "height", "lag"), np.full((n, 1, 3), 1000)),
            "radial_velocity_variance": (("time", "height"), var[:, None]),
            "wind_speed": (("time", "height"), np.full((n, 1), 9.0)),
            "azimuth_step": ("time", np.full(n, dtheta)),
            "scan_period": ("time", np.full(n, 7.0)),
            "n_scans": ("time", np.full(n, 10)),
        },
        coords={
            "time": np.datetime64("2024-01-01T00:00", "ns")
            + np.arange(n) * np.timedelta64(70, "s"),
            "height": [300.0],
            "range": ("height", [rng_m]),
            "lag": [1, 2, 3],
            "elevation": ("time", np.full(n, 30.0)),
        },
    )
    return sf, lm.scales[k]


@pytest.mark.slow
def test_cw_noise_is_pooled_over_neighbouring_blocks(tmp_path):
    """Seven blocks with the same sigma_e = 0.05 m/s; one block's D_L(1) is raised.

    Each block's own 3-parameter fit reads the raised lag as noise; pooled (median over
    the 7 blocks) the noise stays 0.05 m/s in every block and the other blocks keep
    their exact eps (the fit then has 2 parameters per block, as the Monte-Carlo study's).
    """
    probe = CWProbe(wavelength_m=10.6e-6, beam_radius_m=0.075)
    sigma2 = np.array([0.8, 1.0, 1.2, 0.9, 1.1, 1.0, 0.95])
    sf, big_l = _exact_blocks(probe, sigma2, 300.0, np.full(7, 0.05))
    sf["structure_function"][3, 0, 0] += 0.02
    options = {
        "cache_dir": str(tmp_path),
        "height_range_m": (250.0, 600.0),
        "outer_scale_range_m": (50.0, 1500.0),
        "mu_max": 0.5,
    }
    kw = dict(probe=probe, lag_number=3, model="exponential", table_options=options)
    pooled = epsilon.estimate_epsilon(sf, **kw)
    alone = epsilon.estimate_epsilon(sf, noise_window_blocks=1, **kw)
    np.testing.assert_allclose(pooled["noise_std"].values[:, 0], 0.05, rtol=0.02)
    assert alone["noise_std"].values[3, 0] > 0.06  # the raised lag read as noise
    eps = epsilon_from_integral_scale(sigma2, big_l, "exponential")
    keep = np.arange(7) != 3
    np.testing.assert_allclose(pooled["epsilon"].values[keep, 0], eps[keep], rtol=0.01)
