"""Attenuated backscatter and depolarisation ratio (Pentikäinen et al. (2020); Vakkari et al.
(2021)): the focus function, the lidar equation, the ratio and its standard error."""

from __future__ import annotations

import numpy as np
import pytest

from cwproc.physics.backscatter import (
    PLANCK_J_S,
    SPEED_OF_LIGHT_M_S,
    LidarConstants,
    attenuated_backscatter,
    depolarisation_ratio,
    effective_receiver_area,
)

C = LidarConstants()
FULL_AREA = np.pi * C.effective_diameter_m**2 / 4


def test_focus_function_is_the_whole_aperture_at_the_focus():
    """A_e(f) = pi D^2 / 4: the defocus term (1 - R/f) vanishes at the focus."""
    assert effective_receiver_area(np.array([2000.0]), 2000.0)[0] == pytest.approx(FULL_AREA)
    near = effective_receiver_area(np.array([500.0, 1000.0, 1500.0, 2000.0]), 2000.0)
    assert np.all(np.diff(near) > 0)  # grows towards the focus


def test_collimated_beam_has_half_the_aperture_at_the_rayleigh_range():
    """Unfocused (Focus range 65535): A_e = (pi D^2/4) / (1 + (pi D^2 / (4 lambda R))^2),
    half the aperture at R = pi D^2 / (4 lambda) = 313.7 m for D = 25 mm, 1.565 um."""
    r0 = np.pi * C.effective_diameter_m**2 / (4 * C.wavelength_m)
    assert r0 == pytest.approx(313.66, abs=0.01)
    for focus in (65535.0, np.inf):
        assert effective_receiver_area(np.array([r0]), focus)[0] == pytest.approx(FULL_AREA / 2)


def test_beta_inverts_the_heterodyne_lidar_equation():
    """SNR = eta E c beta A_e / (2 h nu B R^2) (Pentikäinen et al. (2020), eqs. 1-3)
    gives back the SNR the beta was computed from."""
    r = np.linspace(60.0, 9000.0, 50)
    snr = np.linspace(-0.01, 0.5, 50)
    beta = attenuated_backscatter(snr, r, 1500.0)
    nu = SPEED_OF_LIGHT_M_S / C.wavelength_m
    forward = (
        C.quantum_efficiency
        * C.pulse_energy_j
        * SPEED_OF_LIGHT_M_S
        * beta
        * effective_receiver_area(r, 1500.0)
        / (2 * PLANCK_J_S * nu * C.receiver_bandwidth_hz * r**2)
    )
    np.testing.assert_allclose(forward, snr, rtol=1e-12, atol=1e-18)


def test_beta_matches_the_values_doppy_computes():
    """Reference: doppy 0.5.16 ``_compute_beta`` (SNR 0.01, Halo defaults), focus 2000 m:
    the same to 1e-6; focus 65535: doppy takes it as 65.5 km, cwproc as infinite, <= 0.5 %
    apart (0.1 % at 3 km; docs/doppler-lidar.md)."""
    r = np.array([100.0, 313.6, 1000.0, 3000.0])
    doppy_2000 = np.array([8.52078531e-09, 1.45156502e-08, 8.83739210e-08, 7.78394075e-07])
    doppy_65535 = np.array([9.32225531e-09, 1.68870905e-08, 9.44811377e-08, 7.83999170e-07])
    np.testing.assert_allclose(
        attenuated_backscatter(np.full(4, 0.01), r, 2000.0), doppy_2000, rtol=1e-6
    )
    ratio = attenuated_backscatter(np.full(4, 0.01), r, 65535.0) / doppy_65535
    assert np.all((ratio > 1.0) & (ratio < 1.005))


def test_constants_must_be_positive():
    with pytest.raises(ValueError, match="pulse_energy_j"):
        LidarConstants(pulse_energy_j=0.0)


def test_depolarisation_of_noise_free_pairs_and_the_bleed_through():
    snr_co = np.array([0.1, 0.02, 0.0, -0.01])
    delta, se = depolarisation_ratio(snr_co, 0.25 * snr_co, 0.0, 0.0, bleed_through=0.01)
    np.testing.assert_allclose(delta[:2], 0.24)
    assert np.isnan(delta[2:]).all() and np.isnan(se[2:]).all()  # no co signal: no ratio


def test_depolarisation_standard_error_is_the_scatter_of_many_realisations():
    """20000 noisy pairs per SNR: the sd of the ratio within 5 % of the stated SE, the
    mean within 3 standard errors of the mean of the truth (first-order error theory
    holds where the co SNR is >= 10 noise sd)."""
    rng = np.random.default_rng(7)
    sd, delta_true, n = 0.002, 0.3, 20000
    for snr in (0.02, 0.05, 0.2):
        co = snr + rng.normal(0, sd, n)
        x = delta_true * snr + rng.normal(0, sd, n)
        delta, se = depolarisation_ratio(co, x, sd, sd)
        assert np.std(delta) == pytest.approx(np.median(se), rel=0.05)
        assert abs(np.mean(delta) - delta_true) < 3 * np.std(delta) / np.sqrt(n) + 0.01 * delta_true
