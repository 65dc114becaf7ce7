"""Exact-statistics virtual lidar (cwproc.sim.exact_gaussian)."""

import numpy as np
import pytest

from cwproc.physics import correlation as corr
from cwproc.physics import spectra
from cwproc.physics.geometry import beam_unit_vector
from cwproc.sim import exact_gaussian as eg
from cwproc.sim.pulsed import range_quadrature

PHI = 35.0
RANGE = 100.0 / np.sin(np.deg2rad(PHI))
L_V = 200.0


@pytest.mark.parametrize("wind", [(0.0, 0.0, 0.0), (3.0, -2.0, 0.0)])
def test_covariance_matches_the_tensor_form_of_banakh_eq15(wind):
    """The structure-function form equals the B-form of sim.turbulence to 1e-5.

    Two independent codings of Banakh et al. (1999), eqs. 15-16 (one contracts B_ik,
    one D_ik) on a 12-ray step-stare scan, with and without transport.
    """
    pattern = eg.conical_pattern(12, 24.0, continuous=False, start_azimuth_deg=-15.0)
    mine = eg.block_covariance(
        pattern,
        1,
        elevation_deg=PHI,
        range_m=RANGE,
        epsilon=1.0,
        outer_scale_m=L_V,
        mean_wind=wind,
    )
    s, w = range_quadrature(15.3, 18.0, 0.5)
    probe = corr.ProbeQuadrature(tuple(RANGE + s), tuple(w))
    ref = corr.azimuth_correlation_matrix(
        corr.ScanGeometry(PHI, 12, 24.0),
        probe,
        sigma2=float(spectra.variance_from(1.0, L_V, "von_karman")),
        outer_scale=L_V,
        mean_wind=None if not any(wind) else np.array([wind[2], wind[1], wind[0]]),
        model="von_karman",
    )
    assert np.abs(mine - ref).max() < 1e-5 * ref[0, 0]


def test_point_probe_is_the_projected_tensor():
    """Point probes: B_D(i, k) = S_i^T B(r) S_k with r the chord (no quadrature)."""
    pattern = eg.conical_pattern(6, 6.0, sector_deg=60.0, continuous=False)
    cov = eg.block_covariance(
        pattern,
        1,
        elevation_deg=PHI,
        range_m=RANGE,
        epsilon=1e-2,
        outer_scale_m=L_V,
        delta_p_m=1e-3,
        delta_r_m=2e-3,
    )
    beams = beam_unit_vector(np.asarray(pattern.azimuth_deg), PHI)
    sigma2 = spectra.variance_from(1e-2, L_V, "von_karman")
    r_vec = RANGE * (beams[0] - beams[1:])
    r = np.linalg.norm(r_vec, axis=-1)
    d_par = spectra.longitudinal_structure_function(r, "von_karman", L_V) * 1e-2 ** (2 / 3)
    d_perp = spectra.transverse_structure_function(r, "von_karman", L_V) * 1e-2 ** (2 / 3)
    p0 = np.sum(beams[0] * r_vec, axis=-1) / r
    pk = np.sum(beams[1:] * r_vec, axis=-1) / r
    dot = beams[1:] @ beams[0]
    expected = sigma2 * dot - 0.5 * (d_perp * dot + (d_par - d_perp) * p0 * pk)
    np.testing.assert_allclose(cov[0, 1:], expected, rtol=2e-4)
    np.testing.assert_allclose(np.diag(cov), sigma2, rtol=1e-6)


@pytest.mark.slow
def test_sweep_average_converges():
    """Continuous-scan rays: 6 (default) and 12 Gauss nodes per half sweep agree on D(l) to 1e-4."""
    pattern = eg.conical_pattern(4, 1.0, sector_deg=8.0)
    kwargs = dict(elevation_deg=PHI, range_m=RANGE, epsilon=1.0, outer_scale_m=L_V)
    d = {}
    for j in (6, 12):
        cov = eg.block_covariance(pattern, 1, sweep_nodes=j, **kwargs)
        d[j] = 2 * (cov[0, 0] - cov[0, 1:])
    np.testing.assert_allclose(d[6], d[12], rtol=1e-4)


def test_transport_correlates_scans_and_no_wind_does_not():
    pattern = eg.conical_pattern(8, 16.0, continuous=False)
    kwargs = dict(elevation_deg=PHI, range_m=RANGE, epsilon=1e-2, outer_scale_m=L_V)
    still = eg.block_covariance(pattern, 3, **kwargs)
    windy = eg.block_covariance(pattern, 3, mean_wind=(2.0, 0.0, 0.0), **kwargs)
    assert np.all(still[:8, 8:] == 0)
    assert np.abs(windy[:8, 8:16]).max() > 0.1 * windy[0, 0]
    np.testing.assert_allclose(windy, windy.T)
    assert np.linalg.eigvalsh(windy).min() > -1e-6 * windy[0, 0]


def test_gap_and_sector_patterns():
    full = eg.conical_pattern(36, 36.0)
    gap = eg.conical_pattern(36, 36.0, gap=(100.0, 60.0))
    sector = eg.conical_pattern(18, 9.0, sector_deg=90.0, start_azimuth_deg=200.0)
    assert full.n_rays == 36 and gap.n_rays == 30
    az = np.asarray(gap.azimuth_deg)
    assert not np.any((az > 100.0) & (az < 160.0))
    assert np.allclose(np.diff(sector.azimuth_deg), 5.0)
    assert 200.0 < min(sector.azimuth_deg) and max(sector.azimuth_deg) < 290.0
    with pytest.raises(ValueError):
        eg.conical_pattern(2, 10.0)


def test_samples_have_the_covariance_and_the_mean_wind():
    """Empirical covariance of 4000 blocks within 4 standard errors of B_D + noise."""
    pattern = eg.conical_pattern(6, 6.0, continuous=False)
    ds = eg.gaussian_scans(
        pattern=pattern,
        n_scans=2,
        n_blocks=4000,
        elevation_deg=PHI,
        ranges_m=[RANGE],
        epsilon=1e-2,
        outer_scale_m=L_V,
        wind_speed_m_s=5.0,
        wind_direction_deg=270.0,
        noise_std_m_s=0.1,
        seed=3,
    )
    assert ds.sizes == {"ray": 4000 * 12, "range": 1}
    assert np.all(ds["qc_flag_radial"] == 0)
    v = ds["radial_velocity"].values[:, 0].reshape(4000, 12)
    beams = beam_unit_vector(np.asarray(pattern.azimuth_deg), PHI)
    mean = np.tile(beams @ np.array([5.0, 0.0, 0.0]), 2)
    cov = eg.block_covariance(
        pattern,
        2,
        elevation_deg=PHI,
        range_m=RANGE,
        epsilon=1e-2,
        outer_scale_m=L_V,
        mean_wind=(5.0, 0.0, 0.0),
    ) + 0.01 * np.eye(12)
    se_mean = np.sqrt(np.diag(cov) / 4000)
    assert np.all(np.abs(v.mean(axis=0) - mean) < 4 * se_mean)
    emp = np.cov(v, rowvar=False)
    se_cov = np.sqrt((cov**2 + np.outer(np.diag(cov), np.diag(cov))) / 4000)
    assert np.all(np.abs(emp - cov) < 4.5 * se_cov)
    times = ds["time"].values
    assert np.all(np.diff(times) > np.timedelta64(0, "ns"))
    assert ds.attrs["sim_epsilon"] == 1e-2
    assert ds.attrs["scan_type"] == "VAD - stepped"  # the beam stands still during a ray


def test_inertial_field_is_refused():
    with pytest.raises(ValueError, match="finite variance"):
        eg.block_covariance(
            eg.conical_pattern(4, 4.0),
            1,
            elevation_deg=PHI,
            range_m=RANGE,
            epsilon=1.0,
            outer_scale_m=L_V,
            model="inertial",
        )


def test_block_assembly_matches_pairwise_times():
    """Two scans as a block equal one 'scan' holding both, each pair at its own times."""
    one = eg.conical_pattern(8, 16.0, continuous=False)
    both = eg.ScanPattern(
        azimuth_deg=one.azimuth_deg * 2,
        time_s=one.time_s + tuple(t + one.period_s for t in one.time_s),
        sweep_deg=0.0,
        dwell_s=one.dwell_s,
        period_s=2 * one.period_s,
    )
    kwargs = dict(
        elevation_deg=PHI, range_m=RANGE, epsilon=1e-2, outer_scale_m=L_V, mean_wind=(3, 1, 0)
    )
    np.testing.assert_allclose(
        eg.block_covariance(one, 2, **kwargs), eg.block_covariance(both, 1, **kwargs), atol=1e-9
    )


@pytest.mark.slow
def test_coarse_continuous_sweep_converges():
    """30 deg sweeps of a 12-ray continuous scan with transport: 6 and 9 nodes agree."""
    pattern = eg.conical_pattern(12, 24.0)
    kwargs = dict(
        elevation_deg=PHI, range_m=RANGE, epsilon=1e-2, outer_scale_m=L_V, mean_wind=(4, -1, 0)
    )
    six = eg.block_covariance(pattern, 1, sweep_nodes=6, **kwargs)
    twelve = eg.block_covariance(pattern, 1, sweep_nodes=9, **kwargs)
    assert np.abs(six - twelve).max() < 2e-4 * twelve[0, 0]


def test_noise_factor_draws_other_noise_than_the_snr_predicts():
    """noise_factor 2: the white noise drawn has twice the sigma_e that the SNR column
    predicts (Pearson et al. (2009), eq. 3); the variance added is 4 times as large."""
    from cwproc.physics import noise

    kwargs = dict(
        pattern=eg.conical_pattern(6, 6.0, continuous=False),
        n_scans=1,
        n_blocks=3000,
        elevation_deg=PHI,
        ranges_m=[RANGE],
        epsilon=1e-2,
        outer_scale_m=L_V,
        wind_speed_m_s=0.0,
        wind_direction_deg=270.0,
        noise_std_m_s=0.1,
        seed=5,
    )
    plain = eg.gaussian_scans(**kwargs)
    doubled = eg.gaussian_scans(**kwargs, noise_factor=2.0)
    attrs = doubled.attrs
    predicted = noise.velocity_noise_std(
        doubled["snr"].values[0, 0],
        attrs["points_per_gate"],
        attrs["pulses_per_ray"],
        noise.bandwidth_from_resolution(attrs["velocity_resolution_m_s"]),
    )
    assert float(predicted) == pytest.approx(0.1, rel=1e-6)
    assert np.all(doubled["snr"].values == plain["snr"].values)
    assert attrs["sim_noise_std"] == pytest.approx(0.2)
    assert attrs["sim_noise_std_predicted"] == pytest.approx(0.1)
    # the same seed: the turbulence is the same draw, the difference is noise 0.1 more
    diff = doubled["radial_velocity"].values - plain["radial_velocity"].values
    assert diff.std() == pytest.approx(0.1, rel=0.03)
