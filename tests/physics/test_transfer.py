"""Probe-volume transfer functions: each is the squared Fourier transform of its weighting."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate

from cwproc.config import InstrumentConfig
from cwproc.physics.transfer import (
    SPEED_OF_LIGHT,
    CWProbe,
    PulsedProbe,
    pulse_parameters,
    transverse,
)
from cwproc.pipeline import probe_from_config


def _power_transfer(weight, kappa, half_width):
    """|int Q(s) exp(-2 pi i kappa s) ds|^2 of a symmetric weighting, by quadrature."""
    out = []
    for k in kappa:
        val, _ = integrate.quad(
            lambda s, k=k: weight(s) * math.cos(2 * math.pi * k * s),
            -half_width,
            half_width,
            limit=2000,
            epsabs=1e-13,
        )
        out.append(val**2)
    return np.array(out)


def test_pulsed_physical_is_transform_of_gaussian_pulse_in_range_gate():
    # Gaussian pulse exp(-s^2/dp^2) (unit area) convolved with the gate of length dR
    dp, dr = 15.3, 18.0
    probe = PulsedProbe(dp, dr, "physical")

    def weight(s):
        a = (s + dr / 2) / dp
        b = (s - dr / 2) / dp
        return (math.erf(a) - math.erf(b)) / (2 * dr)

    kappa = np.array([0.0, 0.005, 0.01, 0.02, 0.03, 0.045])
    numeric = _power_transfer(weight, kappa, 200.0)
    np.testing.assert_allclose(probe.longitudinal(kappa), numeric, rtol=1e-7, atol=1e-12)


def test_pulsed_printed_is_eq19_as_printed():
    probe = PulsedProbe(15.3, 18.0, "printed")
    k = np.array([0.0, 0.01, 0.03])
    expected = (np.exp(-((15.3 * k) ** 2)) * np.sinc(18.0 * k)) ** 2
    np.testing.assert_allclose(probe.longitudinal(k), expected, rtol=1e-14)
    # the printed form lets through more small scales than the physical one
    assert np.all(probe.longitudinal(k[1:]) > PulsedProbe().longitudinal(k[1:]))


def test_cw_lorentzian_transfer_is_transform_of_lorentzian():
    probe = CWProbe(0.0013)
    rng = 100.0
    z_r = 0.0013 * rng**2
    assert probe.rayleigh_half_width(rng) == pytest.approx(13.0)
    # unit area
    area, _ = integrate.quad(lambda s: probe.weighting(s, rng), -np.inf, np.inf)
    assert area == pytest.approx(1.0, rel=1e-9)
    kappa = np.array([0.001, 0.005, 0.01, 0.03])
    numeric = []
    for k in kappa:
        # QAWF: Fourier integral over [0, inf) of the slowly decaying Lorentzian
        val, _ = integrate.quad(
            lambda s: probe.weighting(s, rng), 0, np.inf, weight="cos", wvar=2 * np.pi * k
        )
        numeric.append((2 * val) ** 2)
    np.testing.assert_allclose(probe.longitudinal(kappa, rng), numeric, rtol=1e-6)
    np.testing.assert_allclose(
        probe.longitudinal(kappa, rng), np.exp(-4 * np.pi * z_r * kappa), rtol=1e-14
    )


def test_cw_rayleigh_range_from_beam_radius():
    lam, a0 = 10.6e-6, 0.075  # Banakh et al. (1999)
    probe = CWProbe(wavelength_m=lam, beam_radius_m=a0)
    z_r = lam * 500.0**2 / (2 * math.pi * a0**2)
    z_d = 2 * math.pi * a0**2 / lam
    # Banakh et al. (1999), Q_s with k0 a0^2 squared: w = z_R / (1 + (R/z_d)^2)
    assert probe.rayleigh_half_width(500.0) == pytest.approx(z_r / (1 + (500.0 / z_d) ** 2))
    with pytest.raises(ValueError):
        CWProbe(beam_radius_m=0.05)  # no wavelength
    with pytest.raises(ValueError):
        CWProbe().longitudinal(0.01, None)


def test_transverse_is_transform_of_uniform_window():
    dy = 5.0
    kappa = np.array([0.0, 0.03, 0.1, 0.25, 0.37])
    numeric = _power_transfer(lambda s: 1 / dy, kappa, dy / 2)
    np.testing.assert_allclose(transverse(kappa, dy), numeric, rtol=1e-9, atol=1e-15)
    np.testing.assert_array_equal(transverse(kappa, 0.0), 1.0)


def test_pulse_parameters_stream_line():
    # Smalikho (2020), after eq. 20: dp = c sigma_p / 2, sigma_p = tau_p/(2 sqrt ln 2)
    tau_p = 2 * math.sqrt(math.log(2)) * 2 * 15.3 / SPEED_OF_LIGHT  # about 170 ns
    t_w = 2 * 18.0 / SPEED_OF_LIGHT  # 120 ns
    assert tau_p == pytest.approx(170e-9, rel=0.01)
    dp, dr = pulse_parameters(tau_p, t_w)
    assert dp == pytest.approx(15.3, rel=1e-12)
    assert dr == pytest.approx(18.0, rel=1e-12)


def test_probe_from_config():
    pulsed = probe_from_config(InstrumentConfig(), pulse_transfer="printed")
    assert pulsed == PulsedProbe(15.3, 18.0, "printed")
    cw = probe_from_config(InstrumentConfig(kind="cw", z_r_coefficient=0.002))
    assert isinstance(cw, CWProbe)
    assert cw.rayleigh_half_width(100.0) == pytest.approx(20.0)
    cw_a0 = probe_from_config(InstrumentConfig(kind="cw", wavelength_m=1.55e-6, beam_radius_m=0.02))
    assert cw_a0.coefficient == pytest.approx(1.55e-6 / (2 * math.pi * 0.02**2))
    with pytest.raises(ValueError, match="sonic"):
        probe_from_config(InstrumentConfig(kind="sonic"))


def test_cw_probe_with_beam_radius_has_the_banakh_half_width_and_centre():
    # seed-000 lidar (lambda = 10.6 um, a0 = 7.5 cm): z_d = 2 pi a0^2/lambda = 3334 m;
    # at R = 1000 m (h = 500 m, phi = 30 deg) w = z_R/(1 + (R/z_d)^2) = 0.917 z_R,
    # the same Lorentzian the simulator draws (cwproc.physics.cw_probe.lorentzian_parameters)
    from cwproc.physics.cw_probe import lorentzian_parameters

    probe = CWProbe(wavelength_m=10.6e-6, beam_radius_m=0.075)
    z_d = 2 * math.pi * 0.075**2 / 10.6e-6
    assert probe.focal_parameter_m == pytest.approx(z_d, rel=1e-12)
    for r in (100.0, 1000.0, 3000.0):
        centre, width = lorentzian_parameters(r, 10.6e-6, 0.075)
        assert float(probe.rayleigh_half_width(r)) == pytest.approx(width, rel=1e-12)
        assert float(probe.focus_centre(r)) == pytest.approx(centre, rel=1e-12)
    z_r = 10.6e-6 * 1000.0**2 / (2 * math.pi * 0.075**2)
    assert z_r / float(probe.rayleigh_half_width(1000.0)) == pytest.approx(1.09, abs=0.005)
    # ZephIR's empirical Z_R = 0.0013 R^2 (Wagner et al. (DTU)) keeps no correction
    zephir = CWProbe(0.0013)
    assert zephir.focal_parameter_m is None
    assert float(zephir.rayleigh_half_width(200.0)) == pytest.approx(0.0013 * 200.0**2)
    assert float(zephir.focus_centre(200.0)) == 200.0
    # near the lidar almost nothing lies behind it: H_par -> exp(-4 pi w kappa) of the
    # narrower (corrected) Lorentzian
    kappa = np.array([1e-3, 1e-2])
    w = float(probe.rayleigh_half_width(100.0))
    np.testing.assert_allclose(
        probe.longitudinal(kappa, 100.0), np.exp(-4 * math.pi * w * kappa), rtol=0.02
    )
    assert probe.key() != CWProbe(probe.coefficient).key()  # distinct cache tables


def test_cut_lorentzian_transform_is_the_transform_of_the_cut_weighting():
    """Banakh et al. (1999) Q_s cut at the lidar (seed 000, R = 1000 m: 9 % behind it).

    Against direct quadrature of int Q(s) exp(-2 pi i kappa s) ds over s >= -a, 1e-6.
    """
    from cwproc.physics.transfer import cut_lorentzian_transform

    w, a = 275.0, 917.0  # half width and centre (m) of the seed-000 probe at R = 1000 m
    norm = 0.5 + math.atan(a / w) / math.pi
    assert 1 - norm == pytest.approx(0.093, abs=0.001)

    def q(s):
        return (w / math.pi) / (w**2 + s**2) / norm

    for k in (1e-5, 1e-4, 1e-3, 1e-2, 0.05):
        parts = []
        for weight in ("cos", "sin"):
            near, _ = integrate.quad(
                q, -a, 200 * w, weight=weight, wvar=2 * math.pi * k, limit=5000
            )
            far, _ = integrate.quad(q, 200 * w, np.inf, weight=weight, wvar=2 * math.pi * k)
            parts.append(near + far)
        numeric = parts[0] - 1j * parts[1]
        got = complex(cut_lorentzian_transform(k, w, a))
        assert abs(got - numeric) < 1e-6 * max(1.0, abs(numeric)) + 1e-9
        assert complex(cut_lorentzian_transform(-k, w, a)) == pytest.approx(numeric.conjugate())
    assert complex(cut_lorentzian_transform(0.0, w, a)) == 1.0
    # the cut edge makes H_par decay like kappa^-2, not exponentially
    probe = CWProbe(wavelength_m=10.6e-6, beam_radius_m=0.075)
    assert float(probe.longitudinal(0.01, 1000.0)) > 1e3 * math.exp(-4 * math.pi * w * 0.01)
