"""Predicted radial-velocity noise (Pearson et al. (2009), eq. 3) against its limits."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cwproc.physics import noise

M, N, B = 10.0, 20000.0, 38.4


def test_low_snr_error_falls_as_one_over_snr():
    s = np.array([1e-5, 1e-4])
    sig = noise.velocity_noise_std(s, M, N, B)
    assert sig[0] / sig[1] == pytest.approx(10.0, rel=1e-3)


def test_high_snr_reaches_the_speckle_floor():
    sig = float(noise.velocity_noise_std(1e6, M, N, B))
    assert sig == pytest.approx(noise.speckle_floor(M, N, B), rel=1e-3)


@pytest.mark.parametrize("snr", [1e-3, 0.05, 10.0])
def test_error_falls_as_the_root_of_the_pulses(snr):
    a = float(noise.velocity_noise_std(snr, M, N, B))
    b = float(noise.velocity_noise_std(snr, M, 4 * N, B))
    assert a / b == pytest.approx(2.0, rel=1e-12)


def test_formula_value_at_one_point():
    # Pearson et al. (2009), eq. 3 written out at SNR = 0.01 (-20 dB)
    snr, dv = 0.01, noise.SPECTRAL_WIDTH_M_S
    alpha = snr / (math.sqrt(2 * math.pi) * dv / B)
    expected = 2 * math.sqrt(math.sqrt(math.pi) / alpha) * dv / math.sqrt(M * N * snr)
    expected *= 1 + alpha / (2 * math.pi)
    assert float(noise.velocity_noise_std(snr, M, N, B)) == pytest.approx(expected, rel=1e-12)
    assert 0.2 < expected < 0.4  # a Stream Line at -20 dB, 20000 pulses, 10 points


def test_invalid_snr_gives_nan_and_bad_settings_raise():
    out = noise.velocity_noise_std([0.0, -1.0, np.nan, 0.1], M, N, B)
    assert np.isnan(out[:3]).all() and np.isfinite(out[3])
    with pytest.raises(ValueError, match="pulses_per_ray"):
        noise.velocity_noise_std(0.1, M, 0.0, B)


def test_bandwidth_from_resolution():
    assert noise.bandwidth_from_resolution(0.0382) == pytest.approx(39.1168)
    assert noise.bandwidth_from_resolution(None) == noise.DEFAULT_BANDWIDTH_M_S
    assert noise.bandwidth_from_resolution(float("nan")) == noise.DEFAULT_BANDWIDTH_M_S


@pytest.mark.parametrize("sigma_e", [0.02, 0.05, 0.1, 0.3, 1.0])
def test_snr_for_noise_std_inverts_the_prediction(sigma_e):
    """The SNR a virtual lidar writes gives back its noise through Pearson et al. eq. 3."""
    bandwidth = noise.bandwidth_from_resolution(0.0382)
    snr = noise.snr_for_noise_std(sigma_e, 6, 10000, bandwidth)
    assert noise.velocity_noise_std(snr, 6, 10000, bandwidth) == pytest.approx(sigma_e, rel=1e-12)


def test_snr_for_noise_at_or_below_the_floor_is_a_strong_return():
    bandwidth = noise.bandwidth_from_resolution(0.0382)
    floor = float(noise.velocity_noise_std(1e12, 6, 10000, bandwidth))
    for sigma_e in (0.0, floor, 0.5 * floor):
        assert noise.snr_for_noise_std(sigma_e, 6, 10000, bandwidth) == noise.SNR_STRONG
    with pytest.raises(ValueError, match="pulses_per_ray"):
        noise.snr_for_noise_std(0.1, 6, 0, bandwidth)
