"""Exact two-beam model (cwproc.physics.two_beam) against its limits and the simulator."""

from __future__ import annotations

import numpy as np
import pytest

from cwproc.physics import afunctions, spectra
from cwproc.physics import correlation as corr
from cwproc.physics import two_beam as tb
from cwproc.physics.cw_probe import lorentzian_quadrature
from cwproc.physics.transfer import CWProbe, PulsedProbe

EL = 60.0
R = 1000.0
RP = R * np.cos(np.radians(EL))


@pytest.mark.parametrize("dtheta", [0.05, 0.5, 2.0])
def test_point_probe_small_angle_is_transverse_inertial(dtheta: float) -> None:
    # Smalikho (2020), eq. 13: D_perp = (8/3) r^(2/3) with r the chord between the beams
    d = tb.two_beam_structure_function(0.0, dtheta, EL, R)
    chord = 2 * RP * np.sin(np.radians(dtheta) / 2)
    assert d == pytest.approx((8 / 3) * chord ** (2 / 3), rel=2e-4)


@pytest.mark.parametrize("dtheta", [1.0, 3.0])
def test_pulsed_small_angle_reduces_to_a_perp(dtheta: float) -> None:
    # step-stare (no sweep): A_perp of Smalikho (2020), eq. 16 with H_perp = 1
    probe = PulsedProbe()
    d = tb.two_beam_structure_function(0.0, dtheta, EL, R, probe=probe)
    a = afunctions.a_perp(np.radians(dtheta) * RP, probe=probe, dy=0.0)
    assert d == pytest.approx(float(a), rel=2e-3)


def test_swept_ray_reduces_to_a_perp_with_transverse_filter() -> None:
    # a ray swept over dtheta: H_perp = sinc^2(pi dy kappa) (Smalikho (2020), eq. 20)
    probe = PulsedProbe()
    dy = np.radians(3.0) * RP
    d = tb.two_beam_structure_function(0.0, 3.0, EL, R, probe=probe, sweep_deg=3.0, n_sweep=8)
    # midpoint rule over 8 sub-beams: error O(n^(-5/3)) from the cusp, 3e-3 here
    assert d == pytest.approx(float(afunctions.a_perp(dy, probe=probe, dy=dy)), rel=5e-3)


def test_small_wind_reduces_to_a2() -> None:
    # Smalikho (2020), eq. 15: theta-average with transport, mu = U/V_s = 0.1
    probe = PulsedProbe()
    n_rays, period = 360, 36.0
    t0 = period / n_rays
    mu = 0.1
    speed = mu * 2 * np.pi * RP / period
    th = np.arange(0.0, 360.0, 5.0)
    d = tb.two_beam_structure_function(
        th,
        th + 3.0,
        EL,
        R,
        probe=probe,
        time_separation_s=3 * t0,
        mean_wind=corr.wind_vector(speed, 70.0),
        sweep_deg=1.0,
        n_sweep=6,
    ).mean()
    a = afunctions.a2(3, np.radians(1.0) * RP, mu, EL, probe=probe)
    assert d == pytest.approx(float(a), rel=5e-3)


def test_structure_function_equals_covariance_form() -> None:
    # D(a, b) = B_aa + B_bb - 2 B_ab, with the uniform-mode term sigma^2 |S_a - S_b|^2
    args = dict(
        probe=PulsedProbe(),
        model="von_karman",
        outer_scale_m=200.0,
        mean_wind=corr.wind_vector(8.0, 30.0),
    )
    baa = tb.two_beam_covariance(10.0, 10.0, EL, R, **args)
    bbb = tb.two_beam_covariance(25.0, 25.0, EL, R, **args)
    bab = tb.two_beam_covariance(10.0, 25.0, EL, R, time_separation_s=-2.0, **args)
    d = tb.two_beam_structure_function(10.0, 25.0, EL, R, time_separation_s=-2.0, **args)
    assert d == pytest.approx(float(baa + bbb - 2 * bab), rel=1e-10)


def test_large_separation_tends_to_twice_passed_variance() -> None:
    # beams far apart (L_V = 20 m << chord): D -> 2 B_aa
    args = dict(probe=PulsedProbe(), model="von_karman", outer_scale_m=20.0)
    d = tb.two_beam_structure_function(0.0, 90.0, EL, R, **args)
    b0 = tb.two_beam_covariance(0.0, 0.0, EL, R, **args)
    assert d == pytest.approx(2 * float(b0), rel=2e-3)


def test_cw_covariance_matches_simulator_matrix() -> None:
    # Banakh et al. (1999), eq. 15 with transport, as built by the simulator
    probe, r, big_l = CWProbe(), 300.0, 200.0
    q = lorentzian_quadrature(
        float(probe.centre_range(r)), float(probe.rayleigh_half_width(r)), 40, 300
    )
    geo = corr.ScanGeometry(EL, 50, 1.0)
    wind = corr.wind_vector(8.0, 30.0)
    s2 = spectra.variance_per_eps23("von_karman", big_l)
    b = corr.azimuth_correlation_matrix(
        geo, q, sigma2=s2, outer_scale=big_l, mean_wind=wind, model="von_karman"
    )
    az, ts = geo.azimuth_deg, geo.time_s
    mine = tb.two_beam_covariance(
        az[0],
        az[:5],
        EL,
        r,
        probe=probe,
        time_separation_s=ts[0] - ts[:5],
        mean_wind=wind,
        model="von_karman",
        outer_scale_m=big_l,
    )
    # the simulator integrates with 40 nodes (300 on the diagonal), this module with 120
    np.testing.assert_allclose(mine, b[0, :5], rtol=1e-3)


def test_inertial_has_no_covariance() -> None:
    with pytest.raises(ValueError, match="inertial"):
        tb.two_beam_covariance(0.0, 1.0, EL, R, model="inertial", outer_scale_m=1.0)


def test_epsilon_scales_as_two_thirds() -> None:
    d1 = tb.two_beam_structure_function(0.0, 15.0, EL, R, probe=PulsedProbe())
    d8 = tb.two_beam_structure_function(0.0, 15.0, EL, R, probe=PulsedProbe(), epsilon=8.0)
    assert d8 == pytest.approx(4.0 * float(d1), rel=1e-12)
