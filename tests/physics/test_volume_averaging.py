"""Volume-averaging model of a conically scanning cw lidar, Wagner et al. (DTU), seed 004."""

from __future__ import annotations

import numpy as np
import pytest

from cwproc.physics import volume_averaging as va

HEIGHTS = np.array([40.0, 60.0, 80.0, 100.0])  # the tower heights of the paper (sect. 4.1)


def test_kaimal_integral_is_analytic():
    """Integral of 105 z u*²/(1 + 33 k z)^(5/3) over k >= 0 is 105/(33*2/3) u*² = 4.7727 u*²."""
    k = np.geomspace(1e-9, 1e4, 200_001)
    for z in (10.0, 100.0):
        total = np.trapezoid(va.kaimal_spectrum(k, z, u_star=0.5) * k, np.log(k))
        assert total == pytest.approx(105.0 / 22.0 * 0.25, rel=2e-3)


def test_focus_range_and_rayleigh_range_of_zephir():
    """R = h/cos30°, Z_R = 0.0013 R² (Wagner et al. (DTU), eq. 2): 100 m -> 115.47 m, 17.33 m."""
    assert va.focus_range(100.0) == pytest.approx(115.4701, rel=1e-6)
    assert va.zephir_rayleigh_range(100.0) == pytest.approx(0.0013 * 115.4701**2, rel=1e-6)


def test_lorentzian_transfer_is_the_squared_fourier_transform_of_the_weight():
    """exp(-4 pi Z_R k) = |FT of the Lorentzian|², checked by direct numerical integration."""
    z_r = 12.0
    s = np.linspace(-2e5, 2e5, 4_000_001)
    w = va.lorentzian_weight(s, z_r)
    assert np.trapezoid(w, s) == pytest.approx(1.0, abs=1e-4)
    for k in (0.002, 0.01, 0.03):
        ft = np.trapezoid(w * np.cos(2 * np.pi * k * s), s)
        assert ft**2 == pytest.approx(va.lorentzian_transfer(k, z_r), rel=2e-3)


def test_azimuth_length_scale_bounds_the_advected_scan_trajectory():
    """l_az = 2h tan30 + U T covers the swept strip: the trajectory's along-wind extent is
    2r + U(T - T_rot/2) (exact for full rotations), i.e. within U T_rot/2 of l_az."""
    for h, u, t in [(50.0, 10.0, 1.0), (50.0, 10.0, 3.0), (100.0, 5.0, 3.0)]:
        _, x, _ = va.scan_trajectory(h, u, t, samples_per_rotation=2000)
        extent = x.max() - x.min()
        l_az = va.azimuth_length_scale(h, u, t)
        assert extent <= l_az
        assert l_az - extent == pytest.approx(u * 0.5, rel=0.02)


def test_scan_transfer_matches_fourier_transform_of_coefficient_functions():
    """Closed forms of Wagner et al. (DTU), eqs. 5-7 against a numerical transform."""
    length = 80.0
    x = np.linspace(-length / 2, length / 2, 200_001)
    weights = {
        "along": (1 + np.cos(4 * np.pi * x / length)) / length,
        "across": (1 - np.cos(4 * np.pi * x / length)) / length,
        "vertical": np.full_like(x, 1.0 / length),
    }
    for component, f in weights.items():
        assert np.trapezoid(f, x) == pytest.approx(1.0, rel=1e-6)
        for k in (0.0, 0.004, 0.0125, 0.03, 0.07):
            ft = np.trapezoid(f * np.cos(2 * np.pi * k * x), x)
            assert va.scan_transfer(k, length, component) == pytest.approx(ft**2, abs=1e-8)


def test_scan_transfer_rejects_unknown_component():
    with pytest.raises(ValueError, match="component"):
        va.scan_transfer(0.01, 50.0, "sideways")


def test_ratio_reproduces_wagner_about_0p8_decreasing_with_height_higher_for_1s():
    """Wagner et al. (DTU), sects. 5.1 and 6: sigma_lidar/sigma_cup ~ 0.8 in flat terrain at
    40-100 m, decreasing with height, higher for 1-s than for 3-s scans.

    Numbers obtained (10-min statistics, Kaimal, Z_R = 0.0013 R²), U = 8 m/s:
    1-s scans 0.850, 0.835, 0.818, 0.800; 3-s scans 0.832, 0.823, 0.809, 0.794
    at 40, 60, 80, 100 m. Over U = 4-12 m/s all lie in 0.76-0.86.
    """
    r1, _ = va.std_ratio_table(HEIGHTS, [4.0, 8.0, 12.0], 1.0)
    r3, _ = va.std_ratio_table(HEIGHTS, [4.0, 8.0, 12.0], 3.0)
    np.testing.assert_allclose(r1[:, 1], [0.850, 0.835, 0.818, 0.800], atol=0.002)
    np.testing.assert_allclose(r3[:, 1], [0.832, 0.823, 0.809, 0.794], atol=0.002)
    for r in (r1, r3):
        assert np.all((r > 0.76) & (r < 0.86))
        assert np.all(np.diff(r, axis=0) < 0)  # decreasing with height
    assert np.all(r1 > r3)
    assert abs(r1.mean() - 0.8) < 0.05 and abs(r3.mean() - 0.8) < 0.05


def test_tp_share_decreases_with_height_and_grows_with_scan_time():
    """Wagner et al. (DTU), sect. 5.2: (TP U)² decreases with height; the longer 3-s scan
    removes more small-scale variance from the fit, which TP then carries.

    Numbers obtained at U = 8 m/s, 40-100 m: 1-s 0.113, 0.089, 0.074, 0.063;
    3-s 0.143, 0.109, 0.088, 0.074 (fractions of the cup's 10-min variance).
    """
    _, s1 = va.std_ratio_table(HEIGHTS, [8.0], 1.0)
    _, s3 = va.std_ratio_table(HEIGHTS, [8.0], 3.0)
    np.testing.assert_allclose(s1[:, 0], [0.113, 0.089, 0.074, 0.063], atol=0.002)
    assert np.all(np.diff(s1[:, 0]) < 0) and np.all(np.diff(s3[:, 0]) < 0)
    assert np.all(s3 > s1)


def test_without_filters_the_ratio_is_one():
    """A lidar with no probe volume and a point scan (l_az -> 0) measures what a cup does."""
    ratio, share = va.std_ratio_and_tp_share(1e-3, 8.0, 1e-6, z_r_coefficient=1e-9, window_s=600.0)
    assert ratio == pytest.approx(1.0, abs=2e-3)
    assert share == pytest.approx(0.0, abs=2e-3)


def test_invalid_arguments_raise():
    with pytest.raises(ValueError):
        va.std_ratio_and_tp_share(-10.0, 8.0, 1.0)
    with pytest.raises(ValueError):
        va.std_ratio_and_tp_share(50.0, 0.0, 1.0)
