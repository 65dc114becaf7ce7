"""Spectra and structure functions: normalisation, limits and the eps-sigma-L relations."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate, special

from cwproc.physics import dissipation, spectra


def test_exact_plane_constant_matches_reference_formula():
    # REFERENCE_VALUES.md section 1.1: C = 0.065239, 0.06 % above the printed 0.0652
    def sin_int(p):
        return integrate.quad(lambda t: math.sin(t) ** p, 0, math.pi / 2)[0]

    formula = (8 / 3) / (
        2
        * (2 * math.pi) ** (2 / 3)
        * (-special.gamma(-2 / 3) / 2)
        * (sin_int(2 / 3) + 8 / 3 * sin_int(8 / 3))
    )
    assert spectra.exact_plane_constant() == pytest.approx(formula, rel=1e-10)
    assert spectra.exact_plane_constant() == pytest.approx(0.065239, abs=5e-7)


@pytest.mark.parametrize("model", ["von_karman", "exponential"])
def test_energy_spectrum_integrates_to_three_halves_variance(model):
    big_l = 80.0
    k = np.geomspace(1e-7, 1e6, 20001)
    energy = integrate.trapezoid(spectra.energy_spectrum(k, model, big_l) * k, np.log(k))
    assert energy == pytest.approx(1.5 * spectra.variance_per_eps23(model, big_l), rel=2e-5)


@pytest.mark.parametrize("model", ["von_karman", "exponential"])
def test_spectra_tend_to_kolmogorov_at_small_scales(model):
    big_l = 100.0
    k = np.array([1e2, 1e3])  # kappa L = 1e4, 1e5
    ratio = spectra.energy_spectrum(k, model, big_l) / spectra.energy_spectrum(k)
    # corrections are O((kappa L)^(-2/3)) for the exponential model
    assert np.all(np.abs(ratio - 1) < 0.02 * (k * big_l / 1e4) ** (-2 / 3))
    plane = spectra.plane_spectrum(k, 0.5 * k, model, big_l) / spectra.plane_spectrum(k, 0.5 * k)
    assert np.all(np.abs(plane - 1) < 0.02)


def test_exponential_series_matches_quadrature_across_the_switch():
    # the series (q >= 0.75) and the quadrature spline (q < 0.75) must join smoothly
    q = np.array([0.6, 0.74, 0.76, 1.0])
    spline = np.exp(spectra._exponential_low_q()(np.log(q)))
    series = spectra._exponential_series(q)
    np.testing.assert_allclose(series, spline, rtol=5e-7)


def test_integral_scale_coefficients():
    # Banakh et al. (1999), eq. 19: c = (2 * 1.21 / C_K)^(3/2) = 1.33 with C_K = 2
    assert spectra.integral_scale_coefficient("exponential") == pytest.approx(1.331, abs=1e-3)
    # von Karman: L_V = integral of the longitudinal correlation; sigma^2 from the spectrum
    big_l = 50.0
    sat = 2 * spectra.variance_per_eps23("von_karman", big_l)

    def f(r):
        return 1 - spectra.longitudinal_structure_function(r, "von_karman", big_l) / sat

    integral_scale = integrate.quad(f, 0, np.inf, limit=400)[0]
    assert integral_scale == pytest.approx(big_l, rel=1e-6)
    c = big_l / spectra.variance_per_eps23("von_karman", big_l) ** 1.5
    assert spectra.integral_scale_coefficient("von_karman") == pytest.approx(c, rel=1e-12)
    assert spectra.integral_scale_coefficient("von_karman") == pytest.approx(0.697, abs=1e-3)

    # the exponential model's L_V is its integral scale to 0.13 %
    def f_exp(r):
        return math.exp(-1.21 * (r / big_l) ** (2 / 3))

    assert integrate.quad(f_exp, 0, np.inf)[0] == pytest.approx(0.9987 * big_l, rel=1e-4)


@pytest.mark.parametrize("model", ["von_karman", "exponential"])
def test_eps_sigma_l_relations_round_trip(model):
    eps, big_l = 0.01, 120.0
    s2 = spectra.variance_from(eps, big_l, model)
    assert dissipation.epsilon_from_integral_scale(s2, big_l, model) == pytest.approx(
        eps, rel=1e-12
    )
    assert spectra.outer_scale_from(s2, eps, model) == pytest.approx(big_l, rel=1e-12)
    assert s2 == pytest.approx(spectra.variance_per_eps23(model, big_l) * eps ** (2 / 3))


@pytest.mark.parametrize("model", ["von_karman", "exponential"])
def test_structure_functions_limits(model):
    big_l = 200.0
    small = np.array([1e-3, 1e-2])
    # Kolmogorov at r << L: D_par = 2 r^(2/3), D_perp = (8/3) r^(2/3) (Smalikho (2020) 12-13)
    np.testing.assert_allclose(
        spectra.longitudinal_structure_function(small, model, big_l),
        2 * small ** (2 / 3),
        rtol=3e-3,
    )
    np.testing.assert_allclose(
        spectra.transverse_structure_function(small, model, big_l),
        8 / 3 * small ** (2 / 3),
        rtol=3e-3,
    )
    # saturation at 2 sigma^2 for r >> L
    sat = 2 * spectra.variance_per_eps23(model, big_l)
    far = np.array([300 * big_l])
    assert spectra.longitudinal_structure_function(far, model, big_l)[0] == pytest.approx(
        sat, rel=1e-6
    )
    assert spectra.transverse_structure_function(far, model, big_l)[0] == pytest.approx(
        sat, rel=1e-5
    )


def test_inertial_plane_spectrum_is_eq18():
    k1, k2 = np.array([0.01, 0.2]), np.array([0.03, 0.05])
    ksq = k1**2 + k2**2
    expected = 0.0652 * ksq ** (-4 / 3) * (1 + 8 / 3 * k2**2 / ksq)
    np.testing.assert_allclose(
        spectra.plane_spectrum(k1, k2, constant=spectra.PRINTED_PLANE_CONSTANT),
        expected,
        rtol=1e-14,
    )


def test_model_errors():
    with pytest.raises(ValueError, match="outer scale"):
        spectra.plane_spectrum(0.1, 0.1, "von_karman")
    with pytest.raises(ValueError, match="unknown"):
        spectra.energy_spectrum(0.1, "kaimal", 10.0)
    with pytest.raises(ValueError):
        spectra.variance_per_eps23("inertial", 10.0)
