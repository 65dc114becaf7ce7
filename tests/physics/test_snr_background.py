"""Background correction of the Stream Line SNR (Manninen et al. (2016); Vakkari et al. (2019))."""

from __future__ import annotations

import numpy as np
import pytest

from cwproc.physics.snr_background import (
    corrected_snr,
    fit_background_shape,
    fit_noise_floor,
    signal_free_gates,
)

RANGE = (np.arange(200) + 0.5) * 30.0  # 30 m gates to 6 km


def _ripple(range_m: np.ndarray, amplitude: float, min_range_m: float = 90.0) -> np.ndarray:
    """Alternating +-amplitude with no component along 1 and r over the fitted gates."""
    alt = amplitude * (-1.0) ** np.arange(range_m.size)
    use = range_m > min_range_m
    design = np.column_stack([np.ones(use.sum()), range_m[use]])
    coef, *_ = np.linalg.lstsq(design, alt[use], rcond=None)
    return alt - (coef[0] + coef[1] * range_m)


def test_linear_background_recovered_exactly_from_stripes():
    """B_m = B (1 + ripple) with a ripple orthogonal to the line: the fit is B itself."""
    true = 1.68e7 * (1.0 + 2.0e-5 * RANGE)
    measured = true + 1.68e7 * _ripple(RANGE, 2e-3)
    fit, model = fit_background_shape(measured, RANGE)
    assert model == "line"
    np.testing.assert_allclose(fit, true, rtol=1e-10)


def test_exponential_near_range_rise_chooses_the_exponential_model():
    """A background with a 400 m exponential rise near the lidar is fitted as such."""
    true = 2.1e7 * (1.0 + 1.0e-6 * RANGE + 0.05 * np.exp(-RANGE / 400.0))
    fit, model = fit_background_shape(true, RANGE)
    assert model == "exponential+line"
    # 400 m lies between grid e-folding lengths (48 log steps 30-6000 m: 11.7 % apart)
    assert np.max(np.abs(fit / true - 1.0)) < 2e-3


def test_peaks_are_clipped_from_the_background_fit():
    true = 1.0e7 * (1.0 - 1.0e-5 * RANGE)
    measured = true.copy()
    measured[[40, 41, 120]] *= 1.3  # detector artefacts
    fit, _ = fit_background_shape(measured, RANGE)
    np.testing.assert_allclose(fit, true, rtol=1e-10)


def test_background_with_too_few_gates_is_refused():
    with pytest.raises(ValueError, match="gates beyond 90 m"):
        fit_background_shape(np.ones(3), np.array([15.0, 45.0, 75.0]))


def test_noise_floor_line_recovered_exactly_from_given_gates():
    """Least squares of a noise-free line through the signal-free gates: a and b exact."""
    a, b = 1.0021, -2.5e-7
    floor = a + b * RANGE
    intensity = np.vstack([floor, floor * 1.01])
    intensity[0, 30:60] += 0.2  # signal, excluded by the mask
    mask = np.ones_like(intensity, dtype=bool)
    mask[0, 30:60] = False
    fitted, coef = fit_noise_floor(intensity, RANGE, mask)
    np.testing.assert_allclose(coef[0], [a, b], rtol=1e-10)
    np.testing.assert_allclose(coef[1], [a * 1.01, b * 1.01], rtol=1e-10)
    np.testing.assert_allclose(fitted[0], floor, rtol=1e-12)


def test_noise_floor_needs_enough_gates():
    mask = np.zeros((1, RANGE.size), dtype=bool)
    mask[0, :5] = True
    fitted, coef = fit_noise_floor(np.ones((1, RANGE.size)), RANGE, mask)
    assert np.isnan(coef).all() and np.isnan(fitted).all()


def _synthetic_rays(n_rays: int, sd: float, seed: int = 5):
    """Rays with a known noise floor F, background stripes and a 0.03 SNR aerosol layer."""
    rng = np.random.default_rng(seed)
    floor = 1.0015 - 1.0e-7 * RANGE
    snr_true = np.zeros((n_rays, RANGE.size))
    snr_true[:, 20:50] = 0.03
    background = 1.7e7 * (1.0 + 1.5e-5 * RANGE)
    measured = background + 1.7e7 * _ripple(RANGE, 3e-3)
    observed = floor * (1.0 + snr_true) + rng.normal(0.0, sd, snr_true.shape)
    # the instrument divides the received power P = B F (1 + snr) by its measured background
    intensity = observed * background / measured
    return intensity, measured, snr_true, floor


def test_known_noise_floor_recovered_by_the_correction():
    """End to end: the corrected SNR of signal-free gates is 0, the floor the truth."""
    sd, n_rays = 1e-3, 60
    intensity, measured, snr_true, floor = _synthetic_rays(n_rays, sd)
    fitted, _ = fit_background_shape(measured, RANGE)
    snr, found, noise = corrected_snr(intensity, RANGE, measured, fitted)
    assert not noise[:, 20:50].any()  # the aerosol layer is never taken for noise
    n_free = noise.sum(axis=1)
    assert n_free.min() > 150  # of 197 gates beyond 90 m, layer +- 2 gates excluded
    # floor: least-squares intercept error per ray ~ sd sqrt(1/n + rbar^2/Sxx); mean of 60
    r = RANGE[noise[0]]
    se_a = sd * np.sqrt(1 / r.size + r.mean() ** 2 / np.sum((r - r.mean()) ** 2)) / np.sqrt(n_rays)
    assert abs(np.mean(found[:, 0]) - floor[0]) < 5 * se_a
    # signal-free gates: SNR mean 0 within 5 standard errors (it was +0.0015 - 1e-7 r before)
    free = snr[noise]
    assert abs(free.mean()) < 5 * sd / np.sqrt(free.size) + 1e-5
    before = intensity[noise] - 1.0
    assert before.mean() > 10 * sd / np.sqrt(before.size)  # the bias that was removed
    # the layer: SNR 0.03 recovered within 5 standard errors of its mean
    layer = snr[:, 20:50]
    assert abs(layer.mean() - snr_true[:, 20:50].mean()) < 5 * sd / np.sqrt(layer.size) + 2e-5


def test_a_ray_full_of_signal_keeps_its_snr():
    """A short-range ray inside an aerosol layer: no noise floor to find, SNR not erased."""
    r = RANGE[:24]  # 24 gates to 720 m, as a boundary-layer VAD
    background = np.full(r.size, 1.7e7)
    snr_true = 0.05 + 0.01 * np.sin(r / 100.0)
    intensity = np.vstack([1.0 + snr_true, 1.0 + 0.9 * snr_true])
    snr, floor, _ = corrected_snr(intensity, r, background, background)
    assert np.isnan(floor).all()
    np.testing.assert_allclose(snr, intensity - 1.0, rtol=1e-12)


def test_signal_free_gates_exclude_near_range():
    intensity = np.ones((2, RANGE.size))
    free = signal_free_gates(intensity, RANGE)
    assert not free[:, RANGE <= 90.0].any() and free[:, RANGE > 90.0].all()
