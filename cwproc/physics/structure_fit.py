"""Least squares of the azimuth structure function, Smalikho (2020), eqs. 4-5.

``<D_L(l dtheta)> = eps^(2/3) A(l dy) + 2 sigma_e^2`` (Smalikho (2020), eq. 4) is linear
in ``eps^(2/3)`` and the noise term ``2 sigma_e^2``: :func:`fit_structure_function` is
its least squares over all valid lags, :func:`eq5_epsilon` its two-lag case (eq. 5).
Pure numpy; the lags are on the last axis of every array.
"""

from __future__ import annotations

import functools
import math

import numpy as np

#: fewest lags for a fitted noise intercept (one residual degree of freedom for its
#: standard error; on exact-statistics 24-ray step-stare scans the three-lag sigma_e came
#: out 5-8 times too large, while 144-ray scans with noise 0.3 m/s recover it; 4 would
#: trade the second for the first, see docs/physics-epsilon.md)
MIN_NOISE_LAGS = 3


#: the noise is fitted only where the predicted 2 sigma_e^2 is at least this share of
#: the smallest structure function of the block (below it, the prediction is used)
NOISE_DETECTABLE = 0.05


#: a fitted sigma_e further than this factor from the predicted one is not kept on its
#: precision alone (flag 32; with the covariance of D only the lower side applies)
NOISE_PLAUSIBLE = 2.0


def eq5_epsilon(d_l: np.ndarray, d_1: np.ndarray, a_l: np.ndarray, a_1: np.ndarray) -> np.ndarray:
    """Two-lag estimate of the dissipation rate (m2 s-3), Smalikho (2020), eq. 5.

    ``eps = [(D(l) - D(1)) / (A(l dy) - A(dy))]^(3/2)``; NaN where either difference is
    not positive.

    Parameters
    ----------
    d_l, d_1 : numpy.ndarray
        Structure function at lags l and 1 (m2 s-2).
    a_l, a_1 : numpy.ndarray
        A-function at lags l and 1 (m^(2/3)).
    """
    num = d_l - d_1
    den = a_l - a_1
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = num / den
    return np.where((num > 0) & (den > 0), ratio, np.nan) ** 1.5


def _lag_sum(x: np.ndarray) -> np.ndarray:
    """Sum over the last axis (the few lags), in order.

    numpy reduces such short rows sequentially too, so the sums are the same; an
    element-wise sum over the lags is several times faster than ``x.sum(-1)`` there.
    """
    return functools.reduce(np.add, np.moveaxis(x, -1, 0), np.zeros(x.shape[:-1]))


#: with the covariance of D over the lags, the fitted noise is kept where the standard
#: error of its intercept is at most this share of the predicted ``2 sigma_pred^2``
#: (sigma_e to about 25 %); a rule on the precision alone: judged by its value (above
#: twice its error), the blocks whose intercept rose by chance kept it and those that fell
#: took the prediction, and the kept sigma_e read 11-31 % high on exact statistics
NOISE_PRECISION = 0.5


#: ... or where the intercept and the predicted ``2 sigma_pred^2`` differ by more than
#: this many standard errors of their difference (both uncertainties: the intercept's and
#: the prediction's, :data:`NOISE_PRIOR_REL_SE`): a prediction too low or too high does
#: not overrule a measured noise; few enough where the prediction is right (4 errors of
#: the intercept alone kept 0.15 % of such blocks)
NOISE_CONTRADICTS = 4.0


#: relative standard error of a predicted ``2 sigma_pred^2`` that no data have calibrated
#: (Pearson et al. (2009), eq. 3 with an assumed signal width 1-2 m s-1: sigma_e to about
#: 25 %); a prediction calibrated on the day's blocks carries its calibration's error
#: (:func:`cwproc.physics.noise.noise_calibration`)
NOISE_PRIOR_REL_SE = 0.5


def intercept_standard_error(a: np.ndarray, w: np.ndarray, d_cov: np.ndarray) -> np.ndarray:
    """Standard error of the least-squares intercept from the covariance of D (m2 s-2).

    The intercept is linear in D, ``b = sum_i c_i D_i`` with
    ``c_i = (sum x^2 - x_i sum x) / (n sum x^2 - (sum x)^2)`` (``x = A``, valid lags),
    so ``SE(b) = sqrt(c^T C c)`` for the covariance ``C`` of the block-mean D over its
    scans. The residual form ``s sqrt(sum x^2 / det)`` assumes lags with independent
    errors; the D of neighbouring lags share their rays, and on exact 180-ray statistics
    it was 2.3 times below the scatter of the intercept, where this one matched it
    (ratio 1.00).

    Parameters
    ----------
    a : numpy.ndarray
        A-function at the lags (last axis).
    w : numpy.ndarray of bool
        Lags in the fit.
    d_cov : numpy.ndarray
        Covariance of D (m4 s-4), shape of ``a`` plus one more lag axis (broadcastable).
    """
    x = np.where(w, a, 0.0)
    sx, sxx = _lag_sum(x), _lag_sum(x * x)
    with np.errstate(invalid="ignore", divide="ignore"):
        det = _lag_sum(w.astype(float)) * sxx - sx**2
    return _intercept_se(x, w, sx, sxx, det, d_cov)


def _intercept_se(
    x: np.ndarray,
    w: np.ndarray,
    sx: np.ndarray,
    sxx: np.ndarray,
    det: np.ndarray,
    d_cov: np.ndarray,
) -> np.ndarray:
    """:func:`intercept_standard_error` from the sums of the fit (``x`` zero off ``w``)."""
    # c^T C c of the symmetric C, term by term over the few lags, each lag's c a
    # contiguous array (C broadcast over the leading axes, not copied; 3 times faster
    # than a batched matmul of 4 x 4 blocks); the lags outside the fit have c = 0 (a
    # covariance is all finite or all NaN per cell)
    n_l = x.shape[-1]
    with np.errstate(invalid="ignore", divide="ignore"):
        inv = 1.0 / det
        c = [np.where(w[..., i], (sxx - sx * x[..., i]) * inv, 0.0) for i in range(n_l)]
    var = 0.0
    for i in range(n_l):
        row = d_cov[..., i, i] * c[i]
        for j in range(i + 1, n_l):
            row = row + 2.0 * d_cov[..., i, j] * c[j]
        var = var + c[i] * row
    return np.sqrt(np.where(var >= 0, var, np.nan))


def _line_fit(d: np.ndarray, a: np.ndarray, valid: np.ndarray) -> dict[str, np.ndarray]:
    """Sums and the least-squares line ``D = slope A + intercept`` over the valid lags.

    ``w`` the lags used, ``x``/``y`` A and D there (0 elsewhere), their sums, ``det``.
    """
    w = valid & np.isfinite(d) & np.isfinite(a)
    n = _lag_sum(w.astype(float))
    x = np.where(w, a, 0.0)
    y = np.where(w, d, 0.0)
    sx, sy = _lag_sum(x), _lag_sum(y)
    sxx, sxy = _lag_sum(x * x), _lag_sum(x * y)
    with np.errstate(invalid="ignore", divide="ignore"):
        det = n * sxx - sx**2
        slope = (n * sxy - sx * sy) / det
        intercept = (sy - slope * sx) / n
    return {
        "w": w,
        "n": n,
        "x": x,
        "y": y,
        "sx": sx,
        "sy": sy,
        "sxx": sxx,
        "sxy": sxy,
        "det": det,
        "slope": slope,
        "intercept": intercept,
    }


def free_intercept(
    d: np.ndarray, a: np.ndarray, valid: np.ndarray, d_cov: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The intercept ``2 sigma_e^2`` of the least squares of Smalikho (2020), eq. 4, free.

    The fit of :func:`fit_structure_function` before any decision: intercept (m2 s-2),
    its standard error from the covariance of D (:func:`intercept_standard_error`; NaN
    without ``d_cov``) and the number of lags in the fit. The data of a whole day give the
    SNR calibration of the predicted noise from these
    (:func:`cwproc.physics.noise.noise_calibration`).
    """
    f = _line_fit(d, a, valid)
    intercept = f["intercept"]
    se = np.full(intercept.shape, np.nan)
    if d_cov is not None:
        se = _intercept_se(f["x"], f["w"], f["sx"], f["sxx"], f["det"], d_cov)
    return intercept, se, f["n"]


#: fewest cells of a height whose covariances of D are pooled into the weights of
#: :func:`weighted_intercept` (fewer: the equal weights of :func:`free_intercept`)
MIN_POOLED_CELLS = 5


def pooled_covariance(d: np.ndarray, d_cov: np.ndarray, usable: np.ndarray) -> np.ndarray:
    """``(height, lag, lag)`` shape of the covariance of D shared by the blocks of a height.

    The mean over the usable blocks (axis 0) of the relative covariance
    ``C_ij / (D_i D_j)``, times ``<D_i> <D_j>`` (the blocks' mean D): weights that do not
    depend on one block's own scatter. NaN for a height with fewer than
    :data:`MIN_POOLED_CELLS` usable blocks.

    Parameters
    ----------
    d : numpy.ndarray
        ``(time, height, lag)`` structure function (m2 s-2).
    d_cov : numpy.ndarray
        ``(time, height, lag, lag)`` covariance of the block-mean D over its scans (m4 s-4).
    usable : numpy.ndarray of bool
        ``(time, height)`` blocks to pool (every lag valid, finite and positive).
    """
    with np.errstate(invalid="ignore", divide="ignore"):
        rel = d_cov / (d[..., :, None] * d[..., None, :])
    ok = usable & np.all(np.isfinite(rel), axis=(-1, -2))
    count = ok.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean_rel = np.where(ok[..., None, None], rel, 0.0).sum(axis=0) / count[:, None, None]
        mean_d = np.where(ok[..., None], d, 0.0).sum(axis=0) / count[:, None]
    out = mean_rel * mean_d[:, :, None] * mean_d[:, None, :]
    return np.where((count >= MIN_POOLED_CELLS)[:, None, None], out, np.nan)


def weighted_intercept(
    d: np.ndarray, a: np.ndarray, weight: np.ndarray, d_cov: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Intercept ``2 sigma_e^2`` of the generalised least squares of Smalikho (2020), eq. 4.

    ``beta = (X^T W^-1 X)^-1 X^T W^-1 D`` with ``X = (A, 1)`` over all lags and ``W``
    the pooled covariance of D of the cell's height (:func:`pooled_covariance`): the
    lags weighted by their errors and correlation, so that the noise term is measured
    about twice as precisely as by equal weights (on exact 72-ray statistics at mu 0 and
    1, 100 blocks, the scatter of the intercepts over blocks fell from 0.8-1.25 to
    0.45-0.65 of the true ``2 sigma_e^2``; on 90- and 180-ray sectors from 0.55-0.64 to
    0.22). The weights are the height's, not the block's: weights from a block's own
    scatter would correlate with its intercept. The standard error is ``sqrt(c^T C c)``
    with ``c`` the intercept's row of the GLS and ``C`` the covariance given.

    Parameters
    ----------
    d, a : numpy.ndarray
        ``(..., lag)`` structure function (m2 s-2) and A-function (m^(2/3)).
    weight : numpy.ndarray
        ``(..., lag, lag)`` (broadcastable) pooled covariance of D (m4 s-4).
    d_cov : numpy.ndarray
        ``(..., lag, lag)`` the cell's covariance of D (m4 s-4).

    Returns
    -------
    (intercept, standard error) : numpy.ndarray
        m2 s-2; NaN where ``weight`` is not finite or singular.
    """
    return gls_intercept(d, a, inverse_weight(weight), d_cov)


def inverse_weight(weight: np.ndarray) -> np.ndarray:
    """``W^-1`` of :func:`weighted_intercept` (``(..., lag, lag)``), NaN where ``W`` is not
    finite or not invertible."""
    good = np.all(np.isfinite(weight), axis=(-1, -2))
    eye = np.eye(weight.shape[-1])
    w_safe = np.where(good[..., None, None], weight, eye)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        try:
            inv = np.linalg.inv(w_safe)
        except np.linalg.LinAlgError:
            inv = np.linalg.pinv(w_safe)
    return np.where(good[..., None, None], inv, np.nan)


def gls_intercept(
    d: np.ndarray, a: np.ndarray, inv: np.ndarray, d_cov: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`weighted_intercept` with the inverse weight ``inv`` (:func:`inverse_weight`).

    Term by term over the few lags (``inv`` and ``d_cov`` broadcast over the leading
    axes, not copied), as :func:`_intercept_se`; NaN wherever an input is.
    """
    n_l = d.shape[-1]
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        wa = [_lag_sum(inv[..., i, :] * a) for i in range(n_l)]  # W^-1 A
        w1 = [_lag_sum(inv[..., i, :]) for i in range(n_l)]  # W^-1 1
        saa = functools.reduce(np.add, (a[..., i] * wa[i] for i in range(n_l)))
        sa1 = functools.reduce(np.add, wa)
        s11 = functools.reduce(np.add, w1)
        det = saa * s11 - sa1**2
        # the intercept's row of (X^T W^-1 X)^-1 X^T W^-1, X = (A, 1)
        c = [(saa * w1[i] - sa1 * wa[i]) / det for i in range(n_l)]
        intercept = functools.reduce(np.add, (c[i] * d[..., i] for i in range(n_l)))
        var = 0.0
        for i in range(n_l):
            row = d_cov[..., i, i] * c[i]
            for j in range(i + 1, n_l):
                row = row + 2.0 * d_cov[..., i, j] * c[j]
            var = var + c[i] * row
    ok = np.isfinite(intercept) & (det > 0)
    se = np.sqrt(np.where(ok & (var >= 0), var, np.nan))
    return np.where(ok, intercept, np.nan), se


def fit_structure_function(
    d: np.ndarray,
    a: np.ndarray,
    valid: np.ndarray,
    noise_prior: np.ndarray | None = None,
    d_cov: np.ndarray | None = None,
    prior_rel_se: np.ndarray | float = NOISE_PRIOR_REL_SE,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Least squares of ``D = eps^(2/3) A + 2 sigma_e^2`` over the lags (last axis).

    Smalikho (2020), eq. 4. The intercept ``2 sigma_e^2`` is *determined* where at least
    :data:`MIN_NOISE_LAGS` lags are valid, it is positive, the predicted
    ``2 sigma_pred^2`` is at least :data:`NOISE_DETECTABLE` of the smallest ``D`` (a
    noise far below ``D`` at the first lag is not measurable: the intercept then
    measures the sampling error of ``D`` and the model's shape; on exact 24-ray VAD
    statistics it came out 6-8 times the true sigma_e, and eps 22 % low), and it is
    measured well enough:

    - with the covariance of D (``d_cov``) and a prediction: the intercept's standard
      error (:func:`intercept_standard_error`) is at most :data:`NOISE_PRECISION` of
      ``2 sigma_pred^2`` and the fitted sigma_e at least the prediction over
      :data:`NOISE_PLAUSIBLE` -- a rule on the precision, not on the value, so the kept
      noise is unbiased but for that floor (1.5 errors or more below the prediction) --
      or the data contradict the prediction, or the prediction leaves no turbulence (the
      slope with the intercept fixed at ``2 sigma_pred^2`` is not positive): a
      prediction from a wrong SNR or wrong settings does not overrule the noise the data
      measure. The test takes both uncertainties (``b`` the intercept, ``s_b`` its error,
      ``s_p = prior_rel_se 2 sigma_pred^2``): they contradict where ``|b - 2
      sigma_pred^2| > NOISE_CONTRADICTS sqrt(s_b^2 + s_p^2)`` (a two-sided z-test);
    - otherwise: the intercept exceeds twice its standard error (``d_cov``'s, or the
      residual form ``s sqrt(sum x^2 / (n sum x^2 - (sum x)^2))``, ``s^2`` the residual
      variance with ``n - 2`` degrees of freedom), or, with a prediction, that error is
      below half of ``2 sigma_pred^2`` and sigma_e within :data:`NOISE_PLAUSIBLE` of it.

    Elsewhere the slope is refitted with the intercept fixed at ``2 sigma_pred^2`` from
    ``noise_prior`` (the noise predicted from the SNR, :mod:`cwproc.physics.noise`), or
    at 0 without a prediction; ``sigma_e`` is then the prediction, or NaN -- never a
    measured 0.

    Parameters
    ----------
    d : numpy.ndarray
        Structure function (m2 s-2), lags on the last axis.
    a : numpy.ndarray
        A-function at the same lags (m^(2/3)).
    valid : numpy.ndarray of bool
        Lags to use.
    noise_prior : numpy.ndarray, optional
        Predicted sigma_e (m s-1), shape of ``d`` without the last axis.
    d_cov : numpy.ndarray, optional
        Covariance of the block-mean D over the lags (m4 s-4), shape of ``d`` plus one
        more lag axis (broadcastable); NaN cells fall back to the residual form.
    prior_rel_se : numpy.ndarray or float
        Relative standard error of the predicted ``2 sigma_pred^2`` (default
        :data:`NOISE_PRIOR_REL_SE`; that of a calibrated prediction is smaller).

    Returns
    -------
    (epsilon, noise_std, determined) : tuple of numpy.ndarray
        eps (m2 s-3), sigma_e (m s-1), and whether sigma_e is the fitted one; NaN where
        fewer than two lags are valid.
    """
    f = _line_fit(d, a, valid)
    n, slope, intercept = f["n"], f["slope"], f["intercept"]
    prior = np.full(slope.shape, np.nan) if noise_prior is None else np.asarray(noise_prior)
    has_prior = np.isfinite(prior)
    se, by_cov = _intercept_error(f, d_cov)
    fixed = np.where(has_prior, 2.0 * np.nan_to_num(prior) ** 2, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        fixed_slope = (f["sxy"] - fixed * f["sx"]) / f["sxx"]
    significant = _intercept_significant(
        intercept, (se, by_cov), fixed, fixed_slope > 0, (has_prior, prior_rel_se)
    )
    determined = (n >= MIN_NOISE_LAGS) & (intercept > 0) & significant
    # a noise term far below the smallest structure function cannot be told from the
    # sampling error of D and the model's shape: the fitted intercept then measures
    # those, not the noise (24-ray VADs: 6-8 times the true sigma_e)
    with np.errstate(invalid="ignore"):
        smallest = functools.reduce(
            np.minimum, np.moveaxis(np.where(f["w"], d, np.inf), -1, 0), np.full(n.shape, np.inf)
        )
        detectable = ~has_prior | (2.0 * prior**2 >= NOISE_DETECTABLE * smallest)
    determined = determined & detectable
    slope = np.where(determined, slope, fixed_slope)
    intercept = np.where(determined, intercept, fixed)
    ok = (n >= 2) & (slope > 0) & np.isfinite(slope)
    eps = np.where(ok, np.where(ok, slope, 1.0) ** 1.5, np.nan)
    noise = np.where(determined, np.sqrt(np.maximum(intercept, 0.0) / 2.0), prior)
    return eps, np.where(ok, noise, np.nan), determined & ok


def _intercept_error(f: dict, d_cov: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """``(standard error of the intercept (m2 s-2), whether from d_cov)`` of the line fit
    ``f`` (:func:`_line_fit`): from the covariance of D where given and finite
    (:func:`_intercept_se`), else the residual form ``s sqrt(sum x^2 / (n sum x^2 -
    (sum x)^2))`` with ``s^2`` the residual variance (``n - 2`` degrees of freedom)."""
    w, n, x, y, det = f["w"], f["n"], f["x"], f["y"], f["det"]
    se = np.full(f["slope"].shape, np.nan)
    if d_cov is not None:
        se = _intercept_se(x, w, f["sx"], f["sxx"], det, d_cov)
    by_cov = np.isfinite(se)
    if not by_cov.all():  # the residual form where the covariance is missing
        with np.errstate(invalid="ignore", divide="ignore"):
            resid = np.where(w, y - f["slope"][..., None] * x - f["intercept"][..., None], 0.0)
            s2 = _lag_sum(resid**2) / (n - 2)
            se = np.where(by_cov, se, np.sqrt(s2 * f["sxx"] / det))
    return se, by_cov


def _intercept_significant(
    intercept: np.ndarray,
    error: tuple[np.ndarray, np.ndarray],
    pred2: np.ndarray,
    turbulent: np.ndarray,
    prior: tuple[np.ndarray, np.ndarray | float],
) -> np.ndarray:
    """Whether the intercept is measured well enough to be kept (the rules of
    :func:`fit_structure_function`). ``error``: its standard error and whether that is
    from the covariance of D; ``pred2``: the predicted ``2 sigma_pred^2`` (0 without a
    prediction); ``turbulent``: the slope with the intercept fixed at ``pred2`` is
    positive; ``prior``: where there is a prediction and its relative standard error."""
    se, by_cov = error
    has_prior, prior_rel_se = prior
    with np.errstate(invalid="ignore", divide="ignore"):
        # kept on its precision (NOISE_PRECISION), above a factor NOISE_PLAUSIBLE below
        # the prediction (an intercept near 0 with a small error is the model's error at
        # the first lags, not a noise: seen on the sample's gridded field, 0.005 m/s for
        # a true 0.1), or above the prediction by NOISE_CONTRADICTS errors (a prediction
        # too low does not overrule the noise the data measure), or where the prediction
        # leaves no turbulence (slope <= 0: the data measure less noise than predicted)
        precise_cov = (se <= NOISE_PRECISION * pred2) & (intercept >= pred2 / NOISE_PLAUSIBLE**2)
        prior_se = np.asarray(prior_rel_se) * pred2
        contradicts = np.abs(intercept - pred2) > NOISE_CONTRADICTS * np.hypot(se, prior_se)
        untenable = ~turbulent
        significant = np.where(
            has_prior, precise_cov | contradicts | untenable, intercept > 2.0 * se
        )
    if not by_cov.all():  # the residual form's rule where the covariance is missing
        with np.errstate(invalid="ignore", divide="ignore"):
            # an error it underestimates (lags share rays), hence also the value's
            # significance, and its "precise" within NOISE_PLAUSIBLE of the prediction
            near_factor = np.abs(np.log(np.maximum(intercept, 1e-300) / pred2)) <= 2.0 * (
                math.log(NOISE_PLAUSIBLE)
            )
            precise = has_prior & (2.0 * se < pred2) & near_factor
            significant = np.where(by_cov, significant, (intercept > 2.0 * se) | precise)
    return significant
