"""Structure functions of sampled series by FFT (Gladkikh et al. (2014), eq. 2).

:func:`structure_function_fft` gives D(j) of every lag j = 1..K of many series at once,
skipping missing samples pairwise, through three correlation sums (one FFT product
each, O(N log N)); :func:`remove_running_mean` removes the centred running mean the
sonic stages take out first (Gladkikh et al. (2014), section 1). Used by the stages
:mod:`cwproc.stages.sonic_sf` and :mod:`cwproc.stages.sonic_turbulence`.
"""

from __future__ import annotations

import numpy as np
from scipy.fft import next_fast_len

__all__ = ["remove_running_mean", "structure_function_fft"]


def remove_running_mean(x: np.ndarray, width: int) -> np.ndarray:
    """Subtract a centred running mean of ``width`` samples along the last axis.

    Missing samples (NaN) are left out of the mean and stay NaN; near the ends of the
    window the mean is taken over the part of the running window that exists.
    Gladkikh et al. (2014), section 1 (1-min running mean).

    Parameters
    ----------
    x : ndarray, shape (..., N)
    width : int
        Running-mean width (samples, >= 1).

    Returns
    -------
    ndarray, same shape as ``x``.
    """
    finite = np.isfinite(x)
    complete = bool(finite.all())
    filled = x if complete else np.where(finite, x, 0.0)
    n = x.shape[-1]
    csum = np.zeros((*x.shape[:-1], n + 1))
    np.cumsum(filled, axis=-1, out=csum[..., 1:])
    idx = np.arange(n)
    lo = np.clip(idx - width // 2, 0, n)
    hi = np.clip(idx - width // 2 + width, 0, n)
    if complete:  # the counts are the window lengths (the same numbers, not summed)
        cnt = (hi - lo).astype(float)
    else:
        ccnt = np.zeros((*x.shape[:-1], n + 1))
        np.cumsum(finite, axis=-1, out=ccnt[..., 1:])
        cnt = ccnt[..., hi] - ccnt[..., lo]
    # in place (a day of windows is ~20 MB per temporary): mean = (csum_hi - csum_lo) / cnt
    mean = csum[..., hi]
    mean -= csum[..., lo]
    with np.errstate(invalid="ignore", divide="ignore"):
        mean /= cnt
    if complete:
        return np.subtract(x, mean, out=mean)
    np.subtract(x, mean, out=mean)
    mean[~finite] = np.nan
    return mean


def structure_function_fft(x: np.ndarray, max_lag: int) -> tuple[np.ndarray, np.ndarray]:
    """Structure function D(j) for lags j = 1..max_lag by FFT, missing samples pairwise.

    D(j) = (1/N_j) sum_m [x(m + j) - x(m)]^2 over the N_j pairs in which both samples
    exist, Gladkikh et al. (2014), eq. 2, evaluated through three correlation sums
    (each one FFT product), O(N log N).

    Parameters
    ----------
    x : ndarray, shape (..., N)
        Series (m s-1); NaN marks missing samples.
    max_lag : int
        Largest lag K (samples).

    Returns
    -------
    d : ndarray, shape (..., K)
        D(j) (m2 s-2), NaN where no pair exists.
    pairs : ndarray, shape (..., K)
        N_j, the number of pairs.
    """
    n = x.shape[-1]
    finite = np.isfinite(x)
    # no sample missing: one transform of the mask serves every series (same values)
    complete = bool(finite.all())
    m = finite.astype(float)
    a = x if complete else np.where(finite, x, 0.0)
    nfft = next_fast_len(n + max_lag + 1, real=True)
    fm = np.fft.rfft(m[(0,) * (m.ndim - 1)] if complete else m, nfft, axis=-1)
    fa = np.fft.rfft(a, nfft, axis=-1)
    fs = np.fft.rfft(a * a, nfft, axis=-1)
    del m, a

    def corr(p: np.ndarray, q: np.ndarray) -> np.ndarray:
        # sum_i p_i q_{i+j} for j = 1..max_lag (the lags copied out of the transform)
        product = np.conj(p)
        product = np.multiply(product, q, out=product if product.shape == q.shape else None)
        return np.fft.irfft(product, nfft, axis=-1)[..., 1 : max_lag + 1].copy()

    pairs = np.rint(corr(fm, fm))
    if complete:
        pairs = np.broadcast_to(pairs, (*x.shape[:-1], max_lag))
    squares = corr(fm, fs)
    squares += corr(fs, fm)
    del fs
    cross = corr(fa, fa)
    del fa
    cross *= 2.0
    squares -= cross
    with np.errstate(invalid="ignore", divide="ignore"):
        squares /= pairs
    d = np.where(pairs > 0, np.maximum(squares, 0.0), np.nan)
    return d, pairs
