"""cw lidar: Q_s, Doppler spectra, centroid estimator, homodyne (Banakh et al. (1999))."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import integrate

from cwproc.physics import cw_probe
from cwproc.sim import cw

LAMBDA, A0 = 10.6e-6, 0.075


def test_corrected_q_s_is_the_squared_form_normalised_after_the_cut():
    """Q_s = {pi z_d [(1 - z/R)^2 + (z/z_d)^2]}^-1, z_d = k0 a0^2, cut at z < 0."""
    R = 600.0
    zd = 2 * np.pi * A0**2 / LAMBDA
    z = np.array([10.0, 300.0, 550.0, 600.0, 2000.0])
    printed_fixed = 1.0 / (np.pi * zd * ((1 - z / R) ** 2 + (z / zd) ** 2))
    kept = 1.0 - cw_probe.fraction_behind_lidar(R, LAMBDA, A0)
    assert cw_probe.probe_weight(z, R, LAMBDA, A0) == pytest.approx(printed_fixed / kept, rel=1e-10)
    near, _ = integrate.quad(cw_probe.probe_weight, 0, 2 * R, args=(R, LAMBDA, A0), points=[R])
    far, _ = integrate.quad(cw_probe.probe_weight, 2 * R, np.inf, args=(R, LAMBDA, A0))
    assert near + far == pytest.approx(1.0, rel=1e-6)
    assert cw_probe.probe_weight(np.array([-5.0]), R, LAMBDA, A0)[0] == 0.0


def test_lorentzian_parameters_and_the_share_behind_the_lidar():
    # REFERENCE_VALUES.md section 3: z_c = R/(1+(R/z_d)^2); up to 9 % behind the lidar
    zc, w = cw_probe.lorentzian_parameters(1000.0, LAMBDA, A0)
    zd = 2 * np.pi * A0**2 / LAMBDA
    assert zc == pytest.approx(1000.0 / (1 + (1000.0 / zd) ** 2))
    assert w == pytest.approx(cw_probe.rayleigh_range(1000.0, LAMBDA, A0) / (1 + (1000 / zd) ** 2))
    assert cw_probe.fraction_behind_lidar(1000.0, LAMBDA, A0) == pytest.approx(0.093, abs=0.002)
    assert cw_probe.fraction_behind_lidar(100.0, LAMBDA, A0) < 0.01
    # ZephIR: z_R = 0.0013 R^2 (Wagner et al. (DTU))
    assert cw.ZEPHIR.z_r_coefficient == pytest.approx(0.0013, rel=1e-9)


def test_quadrature_integrates_the_probe_weight():
    R = 400.0
    quad = cw_probe.cw_probe_quadrature(R, LAMBDA, A0, 40)
    assert quad.w.sum() == pytest.approx(1.0)
    f = lambda z: np.exp(-(((z - 380.0) / 150.0) ** 2))  # noqa: E731
    exact, _ = integrate.quad(
        lambda z: cw_probe.probe_weight(z, R, LAMBDA, A0) * f(z), 0, 3000.0, points=[R], limit=200
    )
    assert quad.w @ f(quad.z) == pytest.approx(exact, rel=1e-4)


def test_spectrum_of_one_velocity_peaks_there_and_the_centroid_recovers_it():
    v = np.array([[5.03]])
    spec = cw.doppler_spectrum(v, np.array([1.0]), resolution=0.1, n_channels=256)
    assert spec.sum() == pytest.approx(1.0, abs=0.01)  # sum_k sinc^2(k - x) = 1
    assert int(np.argmax(spec)) == 50
    res = cw.centroid_velocity(spec, resolution=0.1)
    assert res.valid[0]
    # a monochromatic signal violates condition (9) (dV << sigma_s): the truncated
    # sinc^2 side lobes leave an error below dV/5
    assert res.velocity[0] == pytest.approx(5.03, abs=0.02)
    on_channel = cw.doppler_spectrum(
        np.array([[5.0]]), np.array([1.0]), resolution=0.1, n_channels=256
    )
    assert cw.centroid_velocity(on_channel, resolution=0.1).velocity[0] == pytest.approx(5.0)


def test_centroid_is_unbiased_for_turbulent_spectra_high_snr():
    """Under conditions (5)-(10) eq. 4 gives the Q_s-weighted mean of eq. 11."""
    rng = np.random.default_rng(4)
    _dr, q = cw_probe.probe_grid(300.0, LAMBDA, A0)
    vr = 7.0 + rng.normal(0.0, 0.6, size=(500, q.size))
    spec = cw.doppler_spectrum(vr, q, resolution=0.1, n_channels=256)
    res = cw.centroid_velocity(spec, resolution=0.1)
    weighted = vr @ q  # eq. 11
    assert res.valid.all()
    err = res.velocity - weighted
    assert abs(err.mean()) < 0.005  # 500 spectra: standard error 0.001 m/s
    assert err.std() < 0.03


def test_homodyne_measures_the_modulus_and_drops_slow_peaks():
    _dr, q = cw_probe.probe_grid(100.0, LAMBDA, A0)
    rng = np.random.default_rng(6)
    base = rng.normal(0.0, 0.2, size=(3, q.size))
    vr = base + np.array([[-6.0], [6.0], [0.4]])
    spec = cw.doppler_spectrum(vr, q, resolution=0.1, n_channels=256, homodyne=True)
    assert spec[0] == pytest.approx(
        cw.doppler_spectrum(-vr[:1], q, resolution=0.1, n_channels=256)[0]
    )
    res = cw.centroid_velocity(spec, resolution=0.1)
    assert res.velocity[0] == pytest.approx(np.abs(vr[0]) @ q, abs=0.02)
    assert res.velocity[0] > 0
    assert not res.valid[2] and np.isnan(res.velocity[2])  # peak below 1 m/s


@pytest.mark.slow
def test_simulated_cw_scans_are_homodyne_and_match_the_probe_average():
    lidar = cw.CWLidar()
    ds, truth = cw.simulate_cw_scans(
        np.random.default_rng(7),
        lidar,
        heights_m=np.array([100.0]),
        wind_speed=np.array([7.77]),
        wind_direction_deg=240.0,
        sigma2=np.array([1.44]),
        outer_scale_m=np.array([200.0]),
        n_scans=2,
        start=np.datetime64("2024-01-01T00:00:00"),
    )
    assert ds.attrs["homodyne"] == 1 and ds.attrs["instrument_kind"] == "cw"
    assert ds.sizes["ray"] == 280
    assert ds["range"].values[0] == pytest.approx(200.0)
    v = ds["radial_velocity"].values[:, 0]
    ok = np.isfinite(v)
    assert 0.7 < ok.mean() < 1.0  # slow peaks near the zero crossings are dropped
    assert np.all(v[ok] >= 0)
    # the centroid of the simulated spectra is |V_D| (eq. 11) where the spectrum is far
    # from 0 m/s (conditions 7-8); below ~3 m/s the folding |V_r| biases it upward
    diff = v - np.abs(truth[:, 0])
    fast = ok & (np.abs(truth[:, 0]) > 3.0)
    assert np.abs(diff[fast]).max() < 0.1
    assert np.median(np.abs(diff[ok])) < 0.03


def test_heterodyne_scans_keep_the_sign_and_match_the_probe_average():
    """A heterodyne lidar's channels span -M_D dV/2 ... +M_D dV/2: negative V_r are kept.

    With channels from 0 m/s (as for the homodyne |V_r|) the negative half of the scan
    fell off the spectrum and the cut spectra near 0 m/s gave centroid errors correlated
    from ray to ray (0.2 m/s at 500 m).
    """
    lidar = cw.CWLidar(homodyne=False)
    assert lidar.first_channel_velocity == pytest.approx(-12.8)
    v, truth = cw.simulate_cw_height(
        np.random.default_rng(3),
        lidar,
        height_m=500.0,
        wind_speed=9.78,
        wind_direction_deg=240.0,
        sigma2=1.02**2,
        outer_scale_m=333.0,
        n_scans=3,
    )
    ok = np.isfinite(v)
    assert (np.abs(truth) >= 1.5).mean() - 0.02 < ok.mean() < 1.0  # only slow peaks go
    assert np.nanmin(v) < -5.0 and np.nanmax(v) > 5.0
    assert np.median(np.abs(v[ok] - truth[ok])) < 0.01
    assert np.sqrt(np.mean((v[ok] - truth[ok]) ** 2)) < 0.1


@settings(max_examples=40, deadline=None)
@given(
    mean=st.floats(min_value=7.0, max_value=12.0),
    spread=st.floats(min_value=0.1, max_value=0.5),
    shift=st.integers(min_value=1, max_value=60),
    seed=st.integers(min_value=0, max_value=2**32 - 1),
)
def test_centroid_moves_with_the_spectrum(mean, spread, shift, seed):
    """Eq. 4 is translation-equivariant: velocities shifted by j dV (j channels) move
    the estimate by j dV while the window stays inside the channels, and a
    homodyne spectrum does not depend on the sign of V_r (eq. 3 with |V_r|)."""
    rng = np.random.default_rng(seed)
    _dr, q = cw_probe.probe_grid(200.0, LAMBDA, A0)
    profile = np.convolve(rng.normal(size=q.size + 20), np.ones(21) / np.sqrt(21), "valid")
    vr = mean + spread * profile
    both = np.stack([vr, vr + shift * 0.1])
    spec = cw.doppler_spectrum(both, q, resolution=0.1, n_channels=256)
    res = cw.centroid_velocity(spec, resolution=0.1)
    assert res.full_window.all()
    # exact up to round-off; where round-off moves a percentile of sigma_s across a
    # channel the window k1 changes by one channel, which moves V_D by < dV/20
    assert res.velocity[1] - res.velocity[0] == pytest.approx(shift * 0.1, abs=0.005)
    mirrored = cw.doppler_spectrum(-vr[None, :], q, resolution=0.1, n_channels=256)
    assert mirrored[0] == pytest.approx(spec[0], abs=1e-12)


def test_spectrum_is_the_sinc_squared_sum_of_eq_3_even_on_a_channel():
    # the closed form a_i/(k - x_i)^2 of doppler_spectrum equals eq. 3 summed with
    # numpy's sinc, to round-off; a velocity exactly on a channel (0/0 there) too
    from cwproc.sim.cw import doppler_spectrum

    rng = np.random.default_rng(11)
    q = rng.uniform(0.0, 1.0, 60)
    q /= q.sum()
    v = rng.normal(4.0, 1.5, (300, 60))
    v[7, 3] = 2.0  # channel 20 exactly
    for homodyne, first in ((True, 0.0), (False, -12.8)):
        got = doppler_spectrum(
            v, q, resolution=0.1, n_channels=256, first_channel_velocity=first, homodyne=homodyne
        )
        x = ((np.abs(v) if homodyne else v) - first) / 0.1
        want = np.einsum("nik,i->nk", np.sinc(np.arange(256) - x[..., None]) ** 2, q)
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15)


@pytest.mark.skipif(cw._sinc2 is None, reason="C extension cwproc.sim._sinc2 not built")
def test_compiled_spectra_equal_the_numpy_sums(monkeypatch):
    """The C sums of eq. 3 (Banakh et al. (1999)) are numpy's, bit for bit, on a channel too."""
    rng = np.random.default_rng(3)
    x = rng.uniform(-5.0, 300.0, (300, 37))
    x[7, 4] = 40.0  # a point exactly on a channel: the sinc fallback of that spectrum
    q = rng.random(37)
    q /= q.sum()
    compiled = cw._sinc2_sum(x, q, 256)
    monkeypatch.setattr(cw, "_use_extension", False)
    assert np.array_equal(compiled, cw._sinc2_sum(x, q, 256))
    assert np.isfinite(compiled).all()


@pytest.mark.parametrize("n", [1, 2, 7, 40, 600])
def test_gauss_legendre_nodes_and_weights_are_scipys(n):
    """The numpy Newton nodes of the probe quadrature (no scipy.special import)."""
    from scipy import special

    x, w = cw_probe.gauss_legendre(n)
    xs, ws = special.roots_legendre(n)
    np.testing.assert_allclose(x, xs, rtol=0, atol=5e-16)
    np.testing.assert_allclose(w, ws, rtol=5e-9)
    # exact for polynomials of degree 2n - 1: int_{-1}^{1} x^(2j) dx = 2 / (2j + 1)
    j = min(n - 1, 20)
    assert w @ x ** (2 * j) == pytest.approx(2.0 / (2 * j + 1), rel=1e-13)
