"""Covariance of the block statistics over the scans: the scatter and the jackknife.

Exact truth: blocks drawn many times from a known model, the scatter of the block means
over the draws against the mean reported variance.
"""

from __future__ import annotations

import numpy as np

from cwproc.physics.block_stats import (
    WindRefit,
    _scan_covariance,
    block_statistics,
    jackknife_covariance,
)
from cwproc.physics.geometry import beam_unit_vector


def test_jackknife_without_a_wind_refit_is_the_scatter_of_the_scans():
    """For block means the jackknife is ``cov / N`` of the per-scan values, to round-off."""
    rng = np.random.default_rng(2)
    per_scan = rng.normal(size=(23, 3, 4))  # blocks of 10, 10 and 3 scans
    per_scan[4, 1, 2] = np.nan  # a scan with a missing statistic is left out
    starts = np.arange(0, 23, 10)
    zero = {"g": np.zeros((23, 3, 3)), "m": np.zeros((23, 3, 3, 3)), "delta": np.zeros((23, 3, 3))}
    np.testing.assert_allclose(
        jackknife_covariance(per_scan, starts, zero), _scan_covariance(per_scan, starts), rtol=1e-10
    )


def _blocks(n_blocks: int, n_scans: int, rng: np.random.Generator) -> tuple:
    """Scans of 24 rays whose wind varies from scan to scan, plus white noise per ray."""
    az = np.arange(24) * 15.0
    beams = beam_unit_vector(az, 60.0)  # (24, 3)
    winds = rng.normal(0.0, 0.5, (n_blocks * n_scans, 1, 3)) + np.array([5.0, 2.0, 0.0])
    v = np.einsum("ai,thi->tah", beams, winds) + rng.normal(0.0, 0.3, (winds.shape[0], 24, 1))
    fitted = np.linalg.lstsq(beams, v[..., 0].T, rcond=None)[0].T[:, None, :]  # per-scan VAD
    starts = np.arange(0, winds.shape[0], n_scans)
    block = np.add.reduceat(fitted, starts, axis=0) / n_scans  # (block, 1, 3)
    vprime = v - np.einsum("ai,thi->tah", beams, np.repeat(block, n_scans, axis=0))
    refit = WindRefit(np.broadcast_to(beams, (winds.shape[0], 24, 3)), fitted, block)
    return vprime, refit


def test_jackknife_takes_in_what_the_block_mean_wind_fit_removes():
    """The variance of V'_L about the block-mean wind: jackknife error matches its scatter.

    Over 4000 blocks of 10 scans the per-scan scatter misses the share of the variance
    that the block-mean fit takes from all scans at once (13 % low here); the jackknife
    over the scans, with the fit redone without each, reports it. The jackknife variance
    is conservative (Efron and Stein, 1981): 5-8 % high here, 2.5-4 % in the standard
    error.
    """
    rng = np.random.default_rng(8)
    vprime, refit = _blocks(4000, 10, rng)
    plain = block_statistics(vprime, 10, 2)
    jack = block_statistics(vprime, 10, 2, refit)
    np.testing.assert_allclose(jack[2], plain[2])  # the statistics themselves agree
    np.testing.assert_allclose(jack[6][..., :2, :2], plain[6][..., :2, :2], rtol=1e-9)
    scatter = np.var(plain[2][:, 0], ddof=1)
    reported_plain = np.mean(plain[6][:, 0, -1, -1])
    reported_jack = np.mean(jack[6][:, 0, -1, -1])
    assert reported_plain < 0.9 * scatter  # the scatter over 4000 blocks: +-2.2 %
    assert 0.97 < reported_jack / scatter < 1.12


def _noisy_vprime(rng: np.random.Generator) -> np.ndarray:
    """(23 scans, 36 azimuths, 5 heights): blocks of 10, 10 and 3; missing values in a
    few columns, a column without any value and a scan without any value at a height."""
    vprime = rng.normal(0.0, 1.0, (23, 36, 5))
    vprime[rng.random(vprime.shape) < 0.01] = np.nan
    vprime[4, :, 2] = np.nan
    vprime[21, 7:9, :] = np.nan
    return vprime


def test_counts_of_values_and_pairs_from_the_columns_with_a_gap():
    """FiniteColumns counts values and pairs as the finite mask counted in full does."""
    from cwproc.physics.block_stats import finite_columns

    vprime = _noisy_vprime(np.random.default_rng(21))
    valid = finite_columns(vprime)
    finite = np.isfinite(vprime)
    assert 0 < valid.scans.size < 23 * 5  # the fast path and the few columns both used
    assert np.array_equal(valid.counts(), finite.sum(axis=1))
    zeroed = np.where(finite, vprime, 0.0)
    assert np.array_equal(valid.values, zeroed[valid.scans, :, valid.heights])
    assert np.all(finite[valid.scans, :, valid.heights].any(axis=1) | ~valid.masks.any(axis=1))
    starts = np.arange(0, 23, 10)
    for lag in (1, 2, 5):
        both = finite[:, lag:] & finite[:, :-lag]
        assert np.array_equal(valid.counts(lag), both.sum(axis=1))
        assert np.array_equal(
            valid.block_pairs(starts, lag), np.add.reduceat(both.astype(float), starts, axis=0)
        )


def _reference_statistics(vprime: np.ndarray, n_scans: int, n_lags: int) -> tuple:
    """D_L, pairs and variance of V'_L with every value masked and counted in full."""
    starts = np.arange(0, vprime.shape[0], n_scans)
    sf, pairs = [], []
    for lag in range(1, n_lags + 1):
        d2 = (vprime[:, lag:] - vprime[:, :-lag]) ** 2
        ok = np.isfinite(d2)
        total = np.add.reduceat(np.where(ok, d2, 0.0).sum(axis=1), starts, axis=0)
        count = np.add.reduceat(ok.sum(axis=1), starts, axis=0)
        with np.errstate(invalid="ignore", divide="ignore"):
            sf.append(np.where(count > 0, total / count, np.nan))
        pairs.append(count)
    ok = np.isfinite(vprime)
    n = np.add.reduceat(ok.sum(axis=1), starts, axis=0).astype(float)
    s1 = np.add.reduceat(np.where(ok, vprime, 0.0).sum(axis=1), starts, axis=0)
    s2 = np.add.reduceat(np.where(ok, vprime**2, 0.0).sum(axis=1), starts, axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        variance = np.where(n > 1, (s2 - s1**2 / n) / (n - 1), np.nan)
    return np.stack(sf, -1), np.stack(pairs, -1), variance


def test_block_statistics_are_the_fully_masked_sums_to_the_bit():
    """Counting and summing the columns with a gap apart change no bit of D_L, the pair
    counts or the variance (sums in azimuth order; pairwise, as numpy's, for a single
    height)."""
    noisy = _noisy_vprime(np.random.default_rng(22))
    for vprime in (noisy, noisy[..., 2:3], noisy[..., 3:4]):
        sf, pairs, variance, *_ = block_statistics(vprime, 10, 4)
        ref_sf, ref_pairs, ref_variance = _reference_statistics(vprime, 10, 4)
        assert sf.tobytes() == ref_sf.tobytes()
        assert np.array_equal(pairs, ref_pairs) and pairs.dtype == np.int64
        assert variance.tobytes() == ref_variance.tobytes()


def test_wind_refit_terms_are_the_masked_sums_over_the_rays_to_the_bit():
    """g and M of every (scan, height) equal the sums over the valid rays in azimuth
    order, masked in full: with a scan missing a ray (its beam NaN) and a value left
    where the beam is missing (left out of the sums)."""
    from cwproc.physics.block_stats import wind_refit_terms

    rng = np.random.default_rng(23)
    vprime = _noisy_vprime(rng)
    beams = np.broadcast_to(beam_unit_vector(np.arange(36) * 10.0, 60.0), (23, 36, 3)).copy()
    beams[5, 3] = np.nan
    vprime[5, 3, :] = np.nan
    beams[12, 30] = np.nan  # V'_L is finite there: that ray is left out
    winds = rng.normal(0.0, 1.0, (23, 5, 3))
    block_winds = rng.normal(0.0, 1.0, (3, 5, 3))
    assert (np.isfinite(vprime).sum(axis=1) == 0).any()  # no value at a height: 0 in g, M
    for h in (slice(None), slice(1, 2)):  # a single height is summed pairwise by numpy
        refit = WindRefit(beams, winds[:, h], block_winds[:, h])
        terms = wind_refit_terms(vprime[..., h], refit, 10)
        ok = np.isfinite(vprime[..., h]) & np.all(np.isfinite(beams), axis=-1)[..., None]
        okf, b = ok.astype(float), np.nan_to_num(beams)
        count = okf.sum(axis=1)
        for i in range(3):
            with np.errstate(invalid="ignore"):
                g = (np.where(ok, vprime[..., h], 0.0) * b[..., i, None]).sum(axis=1) / count
            assert terms["g"][..., i].tobytes() == np.nan_to_num(g).tobytes()
            for j in range(3):
                with np.errstate(invalid="ignore"):
                    m = (okf * (b[..., i] * b[..., j])[..., None]).sum(axis=1) / count
                assert terms["m"][..., i, j].tobytes() == np.nan_to_num(m).tobytes()


def test_angles_modulo_a_turn_are_numpy_mod_to_the_bit():
    """``_mod_turn`` equals ``numpy.mod(x, 2 pi)`` bit for bit: below 4 pi by exact steps
    (multiples of pi/2 and their neighbours, signed zeros, tiny negatives that round up
    to 2 pi), beyond by numpy itself."""
    from cwproc.physics.block_stats import _mod_turn

    turn = 2.0 * np.pi
    rng = np.random.default_rng(24)
    edges = np.array([k * np.pi / 2 for k in range(-7, 8)] + [0.0, -0.0, -1e-300, 5e-324])
    edges = np.concatenate([edges, np.nextafter(edges, np.inf), np.nextafter(edges, -np.inf)])
    near = np.concatenate([rng.uniform(-1e-12, 1e-12, 1000) + c for c in (-turn, 0.0, turn)])
    angles = np.concatenate([rng.uniform(-2 * turn, 2 * turn, 100_000), edges, near])
    angles = angles[np.abs(angles) < 2 * turn]
    assert _mod_turn(angles).tobytes() == np.mod(angles, turn).tobytes()
    wide = rng.uniform(-50.0, 50.0, 1000)
    assert _mod_turn(wide).tobytes() == np.mod(wide, turn).tobytes()
