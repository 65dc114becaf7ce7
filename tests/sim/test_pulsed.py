"""Pulsed conical-scan sampler: range weighting, geometry, noise, advection, schema."""

from __future__ import annotations

import numpy as np
import pytest

from cwproc.physics.geometry import radial_velocity, wind_components
from cwproc.physics.transfer import PulsedProbe
from cwproc.sim.field3d import FrozenField, von_karman_field
from cwproc.sim.pulsed import pulsed_range_weight, range_quadrature, sample_conical_scans

DP, DR = 15.3, 18.0  # Stream Line, Smalikho (2020) after eq. 20


def zero_field(shape=(16, 16, 8), spacing=4.0) -> FrozenField:
    return FrozenField(np.zeros((3, *shape)), spacing, 0.01, 50.0, 0)


def test_range_weight_transform_is_the_physical_transfer_function():
    # |FT Q|^2 = [exp(-(pi dp k)^2) sinc(pi dR k)]^2 (Smalikho (2020) eq. 19 with pi)
    s = np.linspace(-120, 120, 24001)
    q = pulsed_range_weight(s, DP, DR)
    assert np.trapezoid(q, s) == pytest.approx(1.0, abs=1e-9)
    kappa = np.array([0.0, 0.005, 0.01, 0.02, 0.04])
    ft = np.trapezoid(q[None, :] * np.cos(2 * np.pi * kappa[:, None] * s[None, :]), s, axis=1)
    np.testing.assert_allclose(ft**2, PulsedProbe(DP, DR).longitudinal(kappa), atol=1e-8)


def test_quadrature_weights_sum_to_one_and_are_symmetric():
    s, w = range_quadrature(DP, DR, 2.0)
    assert w.sum() == pytest.approx(1.0)
    np.testing.assert_allclose(w, w[::-1])
    assert s[-1] >= DR / 2 + 3 * DP


def test_mean_wind_alone_gives_the_vad_sine_wave():
    u, v = wind_components(8.0, 225.0)  # from south-west: blowing to north-east
    assert u == pytest.approx(8.0 / np.sqrt(2)) and v == pytest.approx(8.0 / np.sqrt(2))
    ds = sample_conical_scans(
        zero_field(),
        elevation_deg=60.0,
        ranges_m=[100.0, 300.0],
        rays_per_scan=360,
        scan_period_s=36.0,
        n_scans=2,
        wind_speed_m_s=8.0,
        wind_direction_deg=225.0,
        vertical_wind_m_s=0.3,
        noise_std_m_s=0.0,
        seed=0,
    )
    expected = radial_velocity(u, v, 0.3, ds["azimuth"].values, 60.0)
    # the sweep over one 1-deg ray averages the sine: relative effect < 1e-4
    np.testing.assert_allclose(ds["radial_velocity"].values[:, 0], expected, atol=1e-3)
    np.testing.assert_allclose(ds["radial_velocity"].values[:, 1], expected, atol=1e-3)


def test_noise_has_the_requested_standard_deviation():
    ds = sample_conical_scans(
        zero_field(),
        elevation_deg=35.3,
        ranges_m=[100.0, 150.0, 200.0],
        rays_per_scan=200,
        scan_period_s=60.0,
        n_scans=5,
        wind_speed_m_s=0.0,
        wind_direction_deg=0.0,
        noise_std_m_s=0.4,
        seed=7,
    )
    vr = ds["radial_velocity"].values
    assert vr.std() == pytest.approx(0.4, rel=0.05)  # 3000 samples
    lag1 = np.corrcoef(vr[1:, 0], vr[:-1, 0])[0, 1]
    assert abs(lag1) < 0.1  # white


def test_frozen_field_is_carried_by_the_wind():
    """Taylor's hypothesis (Smalikho (2020) eq. 7): a shift of one period repeats the scan."""
    field = von_karman_field((32, 32, 16), 4.0, epsilon=0.01, integral_scale_m=30.0, seed=2)
    period = field.extent_m[0]  # 128 m
    kwargs = dict(
        elevation_deg=35.3,
        ranges_m=[60.0],
        rays_per_scan=90,
        scan_period_s=16.0,
        n_scans=2,
        wind_direction_deg=270.0,  # from the west: carries the field along +x
        noise_std_m_s=0.0,
        seed=0,
    )
    whole = sample_conical_scans(field, wind_speed_m_s=period / 16.0, **kwargs)
    half = sample_conical_scans(field, wind_speed_m_s=0.5 * period / 16.0, **kwargs)
    vr = whole["radial_velocity"].values[:, 0]
    mean_w = radial_velocity(period / 16.0, 0.0, 0.0, whole["azimuth"].values, 35.3)
    # scan 1 sees the field shifted by exactly one period: same fluctuations as scan 0
    np.testing.assert_allclose((vr - mean_w)[:90], (vr - mean_w)[90:], atol=1e-9)
    vr_h = half["radial_velocity"].values[:, 0]
    mean_h = radial_velocity(0.5 * period / 16.0, 0.0, 0.0, half["azimuth"].values, 35.3)
    assert np.max(np.abs((vr_h - mean_h)[:90] - (vr_h - mean_h)[90:])) > 0.05


def test_output_is_a_canonical_scan_dataset():
    ds = sample_conical_scans(
        zero_field(),
        elevation_deg=20.0,
        ranges_m=[90.0, 120.0],
        rays_per_scan=72,
        scan_period_s=30.0,
        n_scans=3,
        wind_speed_m_s=5.0,
        wind_direction_deg=10.0,
        noise_std_m_s=0.1,
        seed=1,
        start_azimuth_deg=350.0,
        clockwise=False,
    )
    assert ds["radial_velocity"].dims == ("ray", "range")
    assert ds["time"].dtype == np.dtype("datetime64[ns]")
    assert ds["scan"].dtype == np.int64
    np.testing.assert_array_equal(np.bincount(ds["scan"].values), [72, 72, 72])
    az = ds["azimuth"].values
    assert np.all((az >= 0) & (az < 360))
    step = ((az[1:] - az[:-1] + 180) % 360) - 180
    np.testing.assert_allclose(step, -5.0)  # counter-clockwise, 360/72 deg
    assert np.all(np.diff(ds["time"].values) > np.timedelta64(0, "ns"))
    for key in ("instrument", "instrument_kind", "system_id", "gate_length_m", "homodyne"):
        assert key in ds.attrs
    assert ds.attrs["instrument"] == "Halo Photonics Stream Line"
    assert ds.attrs["sim_noise_std"] == 0.1


def test_bad_arguments_are_rejected():
    with pytest.raises(ValueError):
        sample_conical_scans(
            zero_field(),
            elevation_deg=20.0,
            ranges_m=[90.0],
            rays_per_scan=2,
            scan_period_s=30.0,
            n_scans=1,
            wind_speed_m_s=5.0,
            wind_direction_deg=10.0,
            noise_std_m_s=0.1,
            seed=1,
        )


def test_sweep_advection_only_matters_with_wind():
    field = von_karman_field((32, 32, 16), 4.0, epsilon=0.01, integral_scale_m=30.0, seed=4)
    kwargs = dict(
        elevation_deg=35.3,
        ranges_m=[60.0],
        rays_per_scan=36,
        scan_period_s=36.0,
        n_scans=1,
        wind_direction_deg=0.0,
        noise_std_m_s=0.0,
        seed=0,
    )
    calm = [
        sample_conical_scans(field, wind_speed_m_s=0.0, sweep_advection=a, **kwargs)
        for a in (True, False)
    ]
    np.testing.assert_allclose(calm[0]["radial_velocity"], calm[1]["radial_velocity"])
    windy = [
        sample_conical_scans(field, wind_speed_m_s=15.0, sweep_advection=a, **kwargs)
        for a in (True, False)
    ]
    diff = windy[0]["radial_velocity"].values - windy[1]["radial_velocity"].values
    assert np.max(np.abs(diff)) > 1e-3


def test_compiled_and_numpy_sampling_agree_and_pieces_make_the_series(monkeypatch):
    # the compiled sweep average (cwproc.sim._trilinear) and the numpy one are the same
    # sums; a series made scan by scan with one noise generator is the series made at once
    import cwproc.sim.pulsed as pulsed

    field = von_karman_field((24, 24, 12), 6.0, epsilon=0.01, integral_scale_m=40.0, seed=4)
    kw = dict(
        elevation_deg=35.3,
        ranges_m=(np.arange(10) + 0.5) * 30.0,
        rays_per_scan=36,
        scan_period_s=18.0,
        wind_speed_m_s=7.0,
        wind_direction_deg=200.0,
        noise_std_m_s=0.1,
        seed=3,
        range_step_m=7.5,
    )
    whole = sample_conical_scans(field, n_scans=3, **kw)
    rng = np.random.default_rng(3)
    parts = [
        sample_conical_scans(field, n_scans=1, first_scan=k, noise_rng=rng, **kw) for k in range(3)
    ]
    joined = np.concatenate([p["radial_velocity"].values for p in parts])
    np.testing.assert_allclose(joined, whole["radial_velocity"].values, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(
        np.concatenate([p["time"].values for p in parts]), whole["time"].values
    )
    late = sample_conical_scans(field, n_scans=1, first_scan=4800, **kw)  # a day on: 600 km
    monkeypatch.setattr(pulsed, "_trilinear", None)
    slow = sample_conical_scans(field, n_scans=3, **kw)
    np.testing.assert_allclose(
        slow["radial_velocity"].values, whole["radial_velocity"].values, rtol=0, atol=1e-12
    )
    slow_late = sample_conical_scans(field, n_scans=1, first_scan=4800, **kw)
    np.testing.assert_allclose(
        slow_late["radial_velocity"].values, late["radial_velocity"].values, rtol=0, atol=1e-9
    )
