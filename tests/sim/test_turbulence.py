"""Correlation models and random fields of the virtual instrument (Banakh et al. (1999))."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate

from cwproc.physics import correlation as corr
from cwproc.physics import dissipation, spectra
from cwproc.physics.cw_probe import cw_probe_quadrature
from cwproc.physics.geometry import beam_unit_vector_une
from cwproc.sim import turbulence as T


def test_eq17_values_and_integral_scale():
    r = np.array([0.0, 100.0, 800.0])
    b = corr.longitudinal_correlation(r, 2.0, 100.0, "exponential")
    assert b[0] == pytest.approx(2.0)
    assert b[1] == pytest.approx(2.0 * np.exp(-1.21))
    assert b[2] == pytest.approx(2.0 * np.exp(-1.21 * 4.0))
    # int_0^inf exp(-1.21 x^(2/3)) dx = (3/2) Gamma(3/2) 1.21^(-3/2) = 0.99875
    val, _ = integrate.quad(
        lambda x: corr.longitudinal_correlation(x, 1.0, 1.0, "exponential"), 0, np.inf
    )
    assert val == pytest.approx(0.998753, rel=1e-4)


def test_von_karman_integral_scale_and_inertial_limit():
    val, _ = integrate.quad(
        lambda x: corr.longitudinal_correlation(x, 1.0, 100.0, "von_karman"), 0, np.inf, limit=400
    )
    assert val == pytest.approx(100.0, rel=1e-5)
    # D = 2 (sigma^2 - B) -> C_k eps^(2/3) r^(2/3) for r << L with eps = c sigma^3/L
    eps = dissipation.epsilon_from_integral_scale(1.0, 100.0, "von_karman")
    r = 0.01
    d = 2.0 * (1.0 - corr.longitudinal_correlation(r, 1.0, 100.0, "von_karman"))
    assert d == pytest.approx(2.0 * eps ** (2 / 3) * r ** (2 / 3), rel=2e-3)


def test_eq19_coefficients():
    assert spectra.integral_scale_coefficient("exponential") == pytest.approx(1.331, abs=1e-3)
    assert spectra.integral_scale_coefficient("von_karman") == pytest.approx(0.6973, abs=1e-3)
    eps = dissipation.epsilon_from_integral_scale(1.23**2, 133.0)
    assert eps == pytest.approx(0.018, abs=0.001)  # the table of Banakh et al. (1999)
    assert spectra.variance_from(eps, 133.0) == pytest.approx(1.23**2)


@pytest.mark.parametrize("model", ["exponential", "von_karman"])
def test_transverse_correlation_is_f_plus_half_r_df_dr(model):
    """Isotropy (Banakh et al. (1999), eq. 16): g = f + (r/2) df/dr, by finite differences."""
    r = np.array([1.0, 30.0, 250.0])
    h = 1e-4
    fd = (
        corr.longitudinal_correlation(r + h, 1.3, 120.0, model)
        - corr.longitudinal_correlation(r - h, 1.3, 120.0, model)
    ) / (2 * h)
    _, g = spectra.correlation_functions(r, model, 120.0)
    f = corr.longitudinal_correlation(r, 1.3, 120.0, model) / 1.3
    assert g == pytest.approx(f + 0.5 * r * fd / 1.3, rel=1e-6)


def test_isotropic_tensor_longitudinal_and_transverse_components():
    """Eq. 16: along r the tensor gives B_V, across r B_V + (r/2) B_V' (for eq. 17:
    B_V [1 - (1.21/3) (r/L)^(2/3)])."""
    sigma2, scale, r = 1.5, 100.0, 37.0
    tensor = corr.correlation_tensor(np.array([r, 0.0, 0.0]), sigma2, scale)
    b = corr.longitudinal_correlation(r, sigma2, scale, "exponential")
    assert tensor[0, 0] == pytest.approx(b)
    transverse = b * (1.0 - 1.21 / 3.0 * (r / scale) ** (2 / 3))
    assert tensor[1, 1] == pytest.approx(transverse)
    assert tensor[2, 2] == pytest.approx(transverse)
    assert tensor[0, 1] == pytest.approx(0.0, abs=1e-15)
    assert corr.correlation_tensor(np.zeros(3), sigma2, scale) == pytest.approx(sigma2 * np.eye(3))


def test_projected_correlation_is_the_contracted_tensor():
    rng = np.random.default_rng(0)
    r_vec = rng.normal(size=(20, 3)) * 50
    s1 = rng.normal(size=(20, 3))
    s1 /= np.linalg.norm(s1, axis=1, keepdims=True)
    s2 = rng.normal(size=(20, 3))
    s2 /= np.linalg.norm(s2, axis=1, keepdims=True)
    full = np.einsum("pi,pij,pj->p", s1, corr.correlation_tensor(r_vec, 1.0, 80.0), s2)
    assert corr.projected_correlation(r_vec, s1, s2, 1.0, 80.0) == pytest.approx(full)


@pytest.fixture(scope="module")
def cw_setup():
    geometry = corr.ScanGeometry(30.0, 140, 7.0)
    probe = cw_probe_quadrature(200.0, 10.6e-6, 0.075, 24, n_fine=200)
    return geometry, probe


def test_azimuth_correlation_matrix_without_wind_is_circulant(cw_setup):
    geometry, probe = cw_setup
    b = corr.azimuth_correlation_matrix(geometry, probe, sigma2=1.0, outer_scale=200.0)
    assert b == pytest.approx(b.T)
    row = corr.circulant_correlation_row(geometry, probe, np.array([200.0]))[0]
    assert b[0] == pytest.approx(row, abs=1e-12)
    assert b[17] == pytest.approx(np.roll(row, 17), abs=1e-12)
    assert np.linalg.eigvalsh(b).min() > 0
    # probe averaging: the variance of V_D is below sigma_V^2, the same-beam integral
    assert b[0, 0] == pytest.approx(corr.same_beam_variance(probe, 1.0, 200.0))
    assert 0.5 < b[0, 0] < 1.0


def test_point_probe_correlation_is_the_projected_tensor():
    geometry = corr.ScanGeometry(30.0, 8, 8.0)
    probe = corr.ProbeQuadrature((300.0,), (1.0,))
    wind = corr.wind_vector(10.0, 270.0)
    b = corr.azimuth_correlation_matrix(
        geometry, probe, sigma2=1.0, outer_scale=150.0, mean_wind=wind
    )
    s = beam_unit_vector_une(geometry.azimuth_deg, 30.0)
    t = geometry.time_s
    r_vec = 300.0 * s[2] - 300.0 * s[5] - wind * (t[2] - t[5])  # Taylor transport
    assert b[2, 5] == pytest.approx(corr.projected_correlation(r_vec, s[2], s[5], 1.0, 150.0))


@pytest.mark.slow
def test_simulated_scan_velocities_have_the_model_covariance(cw_setup):
    geometry, probe = cw_setup
    wind = (0.0, -4.0, -6.9)
    factor = T.scan_cholesky(geometry, probe, 200.0, wind)
    b = corr.azimuth_correlation_matrix(
        geometry, probe, sigma2=1.0, outer_scale=200.0, mean_wind=np.array(wind)
    )
    v = T.simulate_scan_velocities(np.random.default_rng(1), factor, 2.0, (4000,))
    cov = v.T @ v / v.shape[0]
    # variance: relative standard error sqrt(2/4000) per azimuth, averaged over 140
    assert np.mean(np.diag(cov)) == pytest.approx(2.0 * b[0, 0], rel=0.02)
    for lag in (1, 3, 10, 40):
        emp = np.mean(np.diag(cov, lag)) / np.mean(np.diag(cov))
        model = np.mean(np.diag(b, lag)) / b[0, 0]
        assert emp == pytest.approx(model, abs=0.03)


def test_along_beam_fluctuations_follow_eq17():
    rng = np.random.default_rng(2)
    x = T.along_beam_fluctuations(rng, 400, 2.0, 1.5, 60.0, size=(3000,))
    assert x.shape == (3000, 400)
    assert np.var(x) == pytest.approx(1.5, rel=0.03)
    for lag in (5, 30, 100):  # 10, 60, 200 m
        emp = np.mean(x[:, :-lag] * x[:, lag:])
        assert emp == pytest.approx(
            corr.longitudinal_correlation(2.0 * lag, 1.5, 60.0, "exponential"), abs=0.05
        )


def test_probe_weighted_moments_match_direct_sums():
    rng = np.random.default_rng(3)
    series = rng.normal(size=(2, 300))
    q = rng.random(25)
    q /= q.sum()
    offsets = np.array([0, 7, 100, 275])
    mean, var = T.probe_weighted_moments(series, q, offsets)
    for k, o in enumerate(offsets):
        seg = series[:, o : o + 25]
        m = seg @ q
        assert mean[:, k] == pytest.approx(m)
        assert var[:, k] == pytest.approx((seg**2) @ q - m**2)


def test_cholesky_factor_is_kept_on_disk_and_read_back_bit_for_bit(tmp_path, monkeypatch):
    # the factor of eq. 15 (+ Cholesky, eq. 21) is written once and read the next run;
    # a damaged file is computed again, never trusted
    from cwproc.physics.correlation import ScanGeometry
    from cwproc.physics.cw_probe import cw_probe_quadrature
    from cwproc.sim.turbulence import scan_cholesky

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    geometry = ScanGeometry(30.0, 24, 7.0)
    probe = cw_probe_quadrature(200.0, 10.6e-6, 0.075, 12, 60)
    args = (geometry, probe, 150.0, (0.0, 3.0, 4.0), "exponential")
    scan_cholesky.cache_clear()
    first = scan_cholesky(*args)
    files = list(tmp_path.rglob("scan-cholesky-*.npz"))
    assert len(files) == 1
    scan_cholesky.cache_clear()
    np.testing.assert_array_equal(scan_cholesky(*args), first)
    files[0].write_bytes(b"damaged")
    scan_cholesky.cache_clear()
    np.testing.assert_array_equal(scan_cholesky(*args), first)
    b = first @ first.T  # unit variance on the diagonal: B_D(0)/sigma^2 < 1 (probe average)
    assert np.all(np.diag(b) < 1.0) and np.all(np.diag(b) > 0.5)
    scan_cholesky.cache_clear()


@pytest.mark.parametrize(("height", "speed", "scale"), [(50.0, 6.9, 133.0), (500.0, 9.78, 333.0)])
def test_interpolated_azimuth_correlation_matrix_matches_eq15(height, speed, scale):
    """The azimuth interpolation of B_D (eq. 15) against the direct quadrature.

    The cw lidar of Banakh et al. (1999) at the lowest and highest height of its table
    (R = 100 m: a 3-m probe, the sharpest f_k(theta); R = 1000 m): every entry within
    1e-4 of the variance (the acceptance tolerance; 5e-7 and 1.1e-6 measured), far below
    the 1e-3 allowed, and the matrix stays positive definite.
    """
    geometry = corr.ScanGeometry(30.0, 140, 7.0)
    probe = cw_probe_quadrature(height / 0.5, 10.6e-6, 0.075, 40)
    wind = corr.wind_vector(speed, 30.0)
    kwargs = {"sigma2": 1.0, "outer_scale": scale, "mean_wind": wind}
    exact = corr.azimuth_correlation_matrix(geometry, probe, **kwargs)
    fast = corr.interpolated_azimuth_correlation_matrix(geometry, probe, **kwargs)
    assert np.array_equal(fast, fast.T)
    assert np.max(np.abs(fast - exact)) <= corr.AZIMUTH_INTERPOLATION_TOLERANCE * exact[0, 0]
    assert np.linalg.eigvalsh(fast).min() > 0


def test_interpolated_azimuth_correlation_matrix_without_wind_is_the_circulant():
    geometry = corr.ScanGeometry(30.0, 36, 7.0)
    probe = cw_probe_quadrature(400.0, 10.6e-6, 0.075, 16, n_fine=100)
    fast = corr.interpolated_azimuth_correlation_matrix(
        geometry, probe, sigma2=1.5, outer_scale=200.0
    )
    exact = corr.azimuth_correlation_matrix(geometry, probe, sigma2=1.5, outer_scale=200.0)
    assert np.max(np.abs(fast - exact)) <= 1e-10


def test_scans_from_the_interpolated_factor_have_the_eq15_structure_function(tmp_path, monkeypatch):
    """The field drawn with the factor of the interpolated B_D keeps the statistics of eq. 15.

    The cw lidar of Banakh et al. (1999) at 100 m (R = 200 m, L_V = 200 m, U = 7.77 m/s):
    6000 scans; the variance and the azimuth structure function
    D(l) = <[V(theta_m + l dtheta) - V(theta_m)]^2> against the exact quadrature's
    2 [B_D(0) - B_D(l)] (standard errors about 2-3 %: 6000 scans of correlated azimuths).
    """
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    geometry = corr.ScanGeometry(30.0, 140, 7.0)
    probe = cw_probe_quadrature(200.0, 10.6e-6, 0.075, 40)
    wind = tuple(corr.wind_vector(7.77, 240.0))
    factor = T.scan_cholesky(geometry, probe, 200.0, wind)
    exact = corr.azimuth_correlation_matrix(
        geometry, probe, sigma2=1.0, outer_scale=200.0, mean_wind=np.asarray(wind)
    )
    v = T.simulate_scan_velocities(np.random.default_rng(5), factor, 1.44, (6000,))
    v = v - v.mean(axis=0)
    assert np.mean(v * v) == pytest.approx(1.44 * exact[0, 0], rel=0.05)
    for lag in (1, 5, 20, 70):
        emp = np.mean((v[:, lag:] - v[:, :-lag]) ** 2)
        model = 2.0 * 1.44 * np.mean(exact[0, 0] - np.diag(exact, lag))
        assert emp == pytest.approx(model, rel=0.06), lag
