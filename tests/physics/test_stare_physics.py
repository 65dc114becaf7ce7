"""Physics of the stare eps (cwproc.physics.stare): constants, limits, closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from cwproc.physics import dissipation, stare


def test_transverse_constant_from_c_k():
    # D_L = 2 a_L I r^(2/3) with I = Gamma(1/3)/(2 * 2/3) -> a_L = 0.4977 for C_K = 2
    assert stare.A_LONGITUDINAL == pytest.approx(0.4977, abs=1e-4)
    assert stare.A_TRANSVERSE == pytest.approx(4 / 3 * 0.4977, abs=1e-4)


def test_band_factor_equals_structure_function_integral():
    # mean-removed variance over a record L of a process with D_T = (8/3) eps^(2/3) r^(2/3):
    # (1/L^2) int_0^L (L - r) D_T(r) dr = (8/3)(3/5 - 3/8) L^(2/3) = 0.6 L^(2/3)
    for length in (30.0, 300.0, 3000.0):
        g = stare.band_variance_factor(length, 1e-3 * length)[()]
        assert g == pytest.approx(0.6 * length ** (2 / 3), rel=0.02)


def test_sharp_band_limits_are_oconnor_closed_form():
    # eps of eq. 4 inverts sigma^2 = (3a/2)(eps/2pi)^(2/3)(L1^(2/3) - LN^(2/3))
    l1, ln, eps, a = 1500.0, 6.7, 1e-3, 0.55
    var = 1.5 * a * (eps / (2 * np.pi)) ** (2 / 3) * (l1 ** (2 / 3) - ln ** (2 / 3))
    assert dissipation.oconnor_epsilon(var, l1, ln, a)[()] == pytest.approx(eps, rel=1e-12)
    assert np.isnan(dissipation.oconnor_epsilon(-1.0, l1, ln)[()])


def test_gate_transfer_limits():
    ratio = stare.gate_transfer_ratio(np.array([1e-4, 1e-2, 1.0]), 15.3, 18.0)
    assert ratio[0] == pytest.approx(1.0, abs=1e-3)  # eddies much longer than the gate
    assert ratio[2] < 0.1  # eddies of 6 m: averaged away
    assert np.all(np.diff(ratio) < 0)
    np.testing.assert_allclose(stare.gate_transfer_ratio([0.1, 1.0], 0.0, 0.0), 1.0)


def test_gate_reduces_the_band_variance_most_for_short_windows():
    short = stare.band_variance_factor(60.0, 2.0, 15.3, 18.0) / stare.band_variance_factor(
        60.0, 2.0
    )
    long = stare.band_variance_factor(3000.0, 2.0, 15.3, 18.0) / stare.band_variance_factor(
        3000.0, 2.0
    )
    assert 0.5 < short[()] < long[()] < 1.0


def test_window_moments_against_numpy():
    rng = np.random.default_rng(3)
    w = rng.standard_normal((40, 3)) ** 3
    w[5, 1] = np.nan
    index = np.repeat([0, 1], 20)
    count, mean, var, skew = stare.window_moments(w, index, 2)
    for k in range(2):
        for g in range(3):
            x = w[index == k, g]
            x = x[np.isfinite(x)]
            assert count[k, g] == x.size
            assert mean[k, g] == pytest.approx(x.mean())
            assert var[k, g] == pytest.approx(x.var())
            m2, m3 = x.var(), np.mean((x - x.mean()) ** 3)
            assert skew[k, g] == pytest.approx(m3 / m2**1.5)


def test_epsilon_standard_error_combines_variance_and_wind():
    se = dissipation.stare_epsilon_standard_error(
        np.array([1.0]), np.array([1.0]), np.array([0.2]), np.array([5.0]), np.array([0.0])
    )
    assert se[0] == pytest.approx(0.3)
    se = dissipation.stare_epsilon_standard_error(
        np.array([1.0]), np.array([1.0]), np.array([0.0]), np.array([5.0]), np.array([1.0])
    )
    assert se[0] == pytest.approx(0.2)
