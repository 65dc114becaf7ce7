"""Block statistics of V'_L: D_L, the variance and their covariance over the scans.

Smalikho (2020), eq. 2, per block of consecutive scans (:func:`block_statistics`), with
the standard errors and the covariance of the block means (:func:`jackknife_covariance`)
that the error bars of eps, sigma_V^2 and L_V take (delta method, stage ``epsilon``),
and the azimuth-node weights of the pairs of each lag (:func:`pair_azimuth_weights`).

Reference: Efron, B. and Stein, C. (1981), The jackknife estimate of variance, Ann.
Statist. 9, 586-596 (``cwproc.references.EFRON_STEIN_1981``): the jackknife variance is
conservative in expectation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cwproc.physics.atable_interp import N_BINS


@dataclass(frozen=True)
class WindRefit:
    """What the block-mean VAD fit of Smalikho (2020), eq. 1 is made of, per scan.

    Attributes
    ----------
    beams : (scan, m, 3) unit vectors of the rays on the azimuth grid (NaN: no ray).
    winds : (scan, height, 3) the scan's VAD wind (u, v, w; m s-1; NaN: none).
    block_winds : (block, height, 3) the block-mean wind removed from V_L (m s-1).
    """

    beams: np.ndarray
    winds: np.ndarray
    block_winds: np.ndarray


def block_sum(values: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Sum over consecutive scans (axis 0) within blocks starting at ``starts``."""
    return np.add.reduceat(values, starts, axis=0)


@dataclass(frozen=True)
class FiniteColumns:
    """Where V'_L ``(scan, m, height)`` is finite, kept per column ``(scan, height)``.

    Commonly all but a few columns hold a value at every azimuth ``m``: only those few
    (``scans``, ``heights``) keep their mask (``masks``) and values (``values``, 0
    where missing), so that counts and sums over the valid values cost a pass over
    them rather than a masking of every value.

    Attributes
    ----------
    finite : (scan, m, height) True where V'_L is a number.
    scans, heights : (k,) the columns with a missing value.
    masks : (k, m) ``finite`` of those columns.
    values : (k, m) V'_L of those columns, 0 where missing (m s-1).
    """

    finite: np.ndarray
    scans: np.ndarray
    heights: np.ndarray
    masks: np.ndarray
    values: np.ndarray

    def sum_over_m(self, full: np.ndarray, gaps: np.ndarray) -> np.ndarray:
        """Sum over axis 1 of ``full`` ``(scan, m, height)`` with its missing values as 0.

        ``full`` may be NaN in the columns with a gap only, whose values with the missing
        ones as 0 are ``gaps`` ``(k, m)``. The same bits as :func:`numpy.sum` of the
        masked values: those columns are summed apart in ``m`` order, as numpy sums an
        axis that is not the last; a single height (which numpy sums pairwise) is
        masked in full.
        """
        if full.shape[2] == 1:
            full = full.copy()
            full[self.scans, :, self.heights] = gaps
            return full.sum(axis=1)
        out = full.sum(axis=1)
        out[self.scans, self.heights] = _ordered_sum(gaps)
        return out

    def counts(self, lag: int = 0) -> np.ndarray:
        """``(scan, height)`` values (``lag`` 0) or pairs ``lag`` apart with both finite."""
        n_t, n_m, n_h = self.finite.shape
        out = np.full((n_t, n_h), max(n_m - lag, 0), dtype=np.int64)
        both = self.masks if lag == 0 else self.masks[:, lag:] & self.masks[:, :-lag]
        out[self.scans, self.heights] = both.sum(axis=1)
        return out

    def block_pairs(self, starts: np.ndarray, lag: int) -> np.ndarray:
        """``(block, m, height)`` pairs ``lag`` apart with both values finite, summed over
        the scans of each block (blocks starting at ``starts``), as floats."""
        n_t, n_m, n_h = self.finite.shape
        sizes = np.diff(np.append(starts, n_t))
        out = np.empty((starts.size, max(n_m - lag, 0), n_h))
        out[:] = sizes[:, None, None]
        k, m = np.nonzero(~(self.masks[:, lag:] & self.masks[:, :-lag]))
        block = np.repeat(np.arange(starts.size), sizes)[self.scans[k]]
        np.subtract.at(out, (block, m, self.heights[k]), 1.0)
        return out


def _ordered_sum(values: np.ndarray) -> np.ndarray:
    """Sum over axis 1 of ``(k, m, ...)`` in ``m`` order from 0, as :func:`numpy.sum`
    adds along an axis that is not the last (the last axis is summed pairwise)."""
    return np.cumsum(values, axis=1)[:, -1] + 0.0  # 0 + x: -0 -> +0, as numpy starts


def _mod_turn(angle: np.ndarray) -> np.ndarray:
    """``numpy.mod(angle, 2 pi)`` (rad), the same bits, by exact steps for ``|angle| < 4 pi``.

    numpy takes the exact remainder ``fmod`` and adds ``2 pi`` (rounded) to a negative
    one; below ``4 pi`` the remainder is ``angle -+ 2 pi`` (exact: Sterbenz's lemma), so
    the same values follow from comparisons and additions, at a fifth of the cost.
    Larger angles go to :func:`numpy.mod`.
    """
    turn = 2.0 * np.pi
    if not np.all(np.abs(angle) < 2.0 * turn):
        return np.mod(angle, turn)
    out = angle - turn * (angle >= turn)
    out += turn * (out < 0.0)  # the remainder of (-4 pi, -2 pi], exact
    out += turn * (out < 0.0)  # a negative remainder + 2 pi, rounded as numpy does
    return out + 0.0  # -0 -> +0, as numpy's


def finite_columns(vprime: np.ndarray) -> FiniteColumns:
    """:class:`FiniteColumns` of ``vprime`` ``(scan, m, height)``."""
    finite = np.isfinite(vprime)
    scans, heights = np.nonzero(~finite.all(axis=1))
    masks = finite[scans, :, heights]
    values = np.where(masks, vprime[scans, :, heights], 0.0)
    return FiniteColumns(finite, scans, heights, masks, values)


def _scan_spread(per_scan: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Standard error of the block mean from the scatter of per-scan values (axis 0).

    ``std(ddof=1) / sqrt(n)`` over the scans of each block with a finite value; NaN with
    fewer than two.
    """
    ok = np.isfinite(per_scan)
    n = block_sum(ok.astype(float), starts)
    s1 = block_sum(np.where(ok, per_scan, 0.0), starts)
    s2 = block_sum(np.where(ok, per_scan**2, 0.0), starts)
    with np.errstate(invalid="ignore", divide="ignore"):
        var = (s2 - s1**2 / n) / (n - 1)
        return np.where(n > 1, np.sqrt(np.maximum(var, 0.0) / n), np.nan)


def _scan_covariance(per_scan: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Covariance of the block means of a statistics vector from its per-scan scatter.

    ``per_scan`` is ``(scan, height, k)``; the scans of a block where all ``k`` values
    are finite are the samples, ``cov(ddof=1) / n``; NaN with fewer than two.

    Returns
    -------
    numpy.ndarray
        ``(block, height, k, k)``.
    """
    ok = np.all(np.isfinite(per_scan), axis=-1)
    x = np.where(ok[..., None], per_scan, 0.0)
    n = block_sum(ok.astype(float), starts)[..., None, None]
    s1 = block_sum(x, starts)
    s2 = block_sum(x[..., :, None] * x[..., None, :], starts)
    with np.errstate(invalid="ignore", divide="ignore"):
        cov = (s2 - s1[..., :, None] * s1[..., None, :] / n) / (n - 1) / n
    return np.where(n > 1, cov, np.nan)


def block_statistics(
    vprime: np.ndarray,
    n_scans: int,
    n_lags: int,
    refit: WindRefit | None = None,
    valid: FiniteColumns | None = None,
) -> tuple[np.ndarray, ...]:
    """D_L, pair counts and variance of V'_L per block of ``n_scans`` consecutive scans.

    Smalikho (2020), eq. 2, with all valid pairs of a block pooled (missing values,
    NaN, are skipped pairwise). The scans of a block are the independent samples of the
    standard errors: per-scan ``D_L(l)``, ``D_L(l) - D_L(1)`` and variance, their
    standard deviation over the block's scans divided by the root of their number
    (scans a rotation apart decorrelate when ``U T_scan`` exceeds the integral scale;
    otherwise the errors are underestimated).

    Parameters
    ----------
    vprime : numpy.ndarray
        ``(scan, m, height)`` deviations V'_L (m s-1) on the azimuth grid of each scan.
    n_scans : int
        Scans per block (the last block may be shorter).
    n_lags : int
        Lags l = 1..n_lags.
    refit : WindRefit, optional
        The beams and per-scan winds of the block-mean VAD fit: the covariance is then
        the jackknife over the scans with that fit redone without each scan
        (:func:`jackknife_covariance`), else the scatter of the per-scan values.
    valid : FiniteColumns, optional
        :func:`finite_columns` of ``vprime`` when the caller has it already.

    Returns
    -------
    (sf, pairs, variance, sf_se, diff_se, variance_se, covariance) : tuple of numpy.ndarray
        ``(block, height, lag)`` D_L (m2 s-2), pair counts, standard errors of D_L and of
        ``D_L(l) - D_L(1)`` (m2 s-2); ``(block, height)`` variance of V'_L (m2 s-2, ddof
        1) and its standard error; ``(block, height, lag + 1, lag + 1)`` covariance of
        the block means of ``(D_L(1), ..., D_L(L), variance)`` (m4 s-4) from their
        per-scan scatter (the errors of estimates that combine them, e.g. eps and L_V
        fitted together, follow by the delta method).
    """
    starts = np.arange(0, vprime.shape[0], n_scans)
    n_h = vprime.shape[2]
    valid = finite_columns(vprime) if valid is None else valid
    sf = np.empty((starts.size, n_h, n_lags))
    pairs = np.empty((starts.size, n_h, n_lags), dtype=np.int64)
    per_stats = np.empty((vprime.shape[0], n_h, n_lags + 1))
    for lag in range(1, n_lags + 1):  # each lag vectorised
        d2 = np.subtract(vprime[:, lag:, :], vprime[:, :-lag, :])
        np.square(d2, out=d2)  # NaN where a value of the pair is missing
        gaps = np.square(valid.values[:, lag:] - valid.values[:, :-lag])
        gaps[~(valid.masks[:, lag:] & valid.masks[:, :-lag])] = 0.0
        per_total = valid.sum_over_m(d2, gaps)
        per_count = valid.counts(lag)
        total = block_sum(per_total, starts)
        count = block_sum(per_count, starts)
        with np.errstate(invalid="ignore", divide="ignore"):
            sf[:, :, lag - 1] = np.where(count > 0, total / count, np.nan)
            per_scan = np.where(per_count > 0, per_total / per_count, np.nan)
        pairs[:, :, lag - 1] = count
        per_stats[:, :, lag - 1] = per_scan
    per_n = valid.counts()
    n_val = block_sum(per_n, starts).astype(float)
    per_s2 = valid.sum_over_m(np.square(vprime), np.square(valid.values))
    s1 = block_sum(valid.sum_over_m(vprime, valid.values), starts)
    s2 = block_sum(per_s2, starts)
    with np.errstate(invalid="ignore", divide="ignore"):
        variance = np.where(n_val > 1, (s2 - s1**2 / n_val) / (n_val - 1), np.nan)
        per_n = per_n.astype(float)
        per_var = np.where(per_n > 1, per_s2 / per_n, np.nan)
    per_stats[:, :, n_lags] = per_var
    spread = _scan_spread(per_stats, starts)  # of D_L(1..L) and the variance
    diff_se = _scan_spread(per_stats[:, :, :n_lags] - per_stats[:, :, :1], starts)
    if refit is None:
        covariance = _scan_covariance(per_stats, starts)
    else:
        terms = wind_refit_terms(vprime, refit, n_scans, valid)
        covariance = jackknife_covariance(per_stats, starts, terms)
    return sf, pairs, variance, spread[..., :n_lags], diff_se, spread[..., n_lags], covariance


def wind_refit_terms(
    vprime: np.ndarray, refit: WindRefit, n_scans: int, valid: FiniteColumns | None = None
) -> dict[str, np.ndarray]:
    """Per-scan sums that give the variance of V'_L of a block without one of its scans.

    Without scan ``k`` the block-mean wind of ``N`` scans moves by
    ``delta_k = (w_k - <w>) / (N - 1)`` and every other scan's ``V'_L`` by ``S delta_k``
    (``S`` the beam), so its mean square by ``2 delta_k g_s + delta_k^T M_s delta_k``
    with ``g_s`` the scan's mean of ``V'_L S`` and ``M_s`` its mean of ``S S^T`` over the
    valid rays. Returns ``g`` (scan, height, 3), ``m`` (scan, height, 3, 3) and
    ``delta`` (scan, height, 3; 0 where the scan has no wind). Sums over the rays as
    the statistics take them, in azimuth order (not a BLAS product), so that a day
    processed in chunks gives the same bits as the whole day; ``M_s`` of a column valid
    at every azimuth is the scan's sum over its beams, formed once per scan.
    ``valid`` is :func:`finite_columns` of ``vprime`` when the caller has it already.
    """
    beam_ok = np.all(np.isfinite(refit.beams), axis=-1)
    valid = finite_columns(vprime) if valid is None else valid
    if valid.finite[~beam_ok].any():  # a value without a beam is left out
        vprime = np.where(beam_ok[..., None], vprime, np.nan)
        valid = finite_columns(vprime)
    beams = np.nan_to_num(refit.beams)
    n_t, n_h = vprime.shape[0], vprime.shape[2]
    g = np.empty((n_t, n_h, 3))
    m = np.empty((n_t, n_h, 3, 3))
    outer = beams[..., :, None] * beams[..., None, :]  # (scan, m, 3, 3) S S^T
    with np.errstate(invalid="ignore", divide="ignore"):
        count = valid.counts().astype(float)
        for i in range(3):
            b_gaps = beams[valid.scans, :, i]
            g[..., i] = valid.sum_over_m(vprime * beams[..., i, None], valid.values * b_gaps)
            g[..., i] /= count
        if n_h > 1:  # a column valid at every m sums its scan's S S^T (m order)
            m[:] = _ordered_sum(outer)[:, None]
            gaps = valid.masks[:, :, None, None] * outer[valid.scans]
            m[valid.scans, valid.heights] = _ordered_sum(gaps)
        else:  # summed pairwise by numpy
            for i, j in np.ndindex(3, 3):
                m[..., i, j] = (valid.finite * outer[..., i, j, None]).sum(axis=1)
        m /= count[..., None, None]
    block = np.arange(n_t) // n_scans
    has_wind = np.all(np.isfinite(refit.winds), axis=-1)
    n_w = np.add.reduceat(has_wind.astype(float), np.arange(0, n_t, n_scans), axis=0)[block]
    with np.errstate(invalid="ignore", divide="ignore"):
        delta = (refit.winds - refit.block_winds[block]) / (n_w - 1.0)[..., None]
    delta = np.where(has_wind[..., None] & (n_w > 1)[..., None], delta, 0.0)
    return {"g": np.nan_to_num(g), "m": np.nan_to_num(m), "delta": delta}


def jackknife_covariance(
    per_scan: np.ndarray, starts: np.ndarray, terms: dict[str, np.ndarray]
) -> np.ndarray:
    """Jackknife covariance of the block means of ``(D_L(1..L), variance)`` over the scans.

    Leave-one-out block means ``theta_k`` over the other valid scans (those with every
    statistic finite), the variance's with the block-mean wind refitted without scan
    ``k`` (:func:`wind_refit_terms`); ``(N - 1)/N sum_k (theta_k - theta)(theta_k -
    theta)^T``. For the D_L, which the wind leaves alone, this is the per-scan scatter's
    ``cov / N`` exactly; the variance's gains what the block-mean fit takes from all
    scans at once (exact 180-ray statistics, 100 blocks: se/sd of sigma_V^2 0.84-0.98 ->
    0.90-1.06; Gaussian per-scan winds: 0.87 -> 1.07 in variance, conservative as
    Efron and Stein (1981) show). NaN with fewer than two scans.

    Returns
    -------
    numpy.ndarray
        ``(block, height, k, k)`` (m4 s-4).
    """
    ok = np.all(np.isfinite(per_scan), axis=-1)
    okf = ok.astype(float)
    x = np.where(ok[..., None], per_scan, 0.0)
    n = block_sum(okf, starts)  # (block, height)
    sizes = np.diff(np.append(starts, per_scan.shape[0]))
    block = np.repeat(np.arange(starts.size), sizes)
    n_k = n[block]
    g = terms["g"] * okf[..., None]
    m = terms["m"] * okf[..., None, None]
    g_rest = block_sum(g, starts)[block] - g
    m_rest = block_sum(m, starts)[block] - m
    delta = terms["delta"]
    shift = np.zeros(n_k.shape)
    for i in range(3):  # 2 delta . g + delta^T M delta, term by term (the same bits in chunks)
        shift += 2.0 * delta[..., i] * g_rest[..., i]
        for j in range(3):
            shift += delta[..., i] * m_rest[..., i, j] * delta[..., j]
    with np.errstate(invalid="ignore", divide="ignore"):
        theta = (block_sum(x, starts)[block] - x) / (n_k - 1.0)[..., None]
        theta[..., -1] += shift / (n_k - 1.0)
        theta = np.where(ok[..., None], theta, 0.0)
        mean = block_sum(theta, starts) / n[..., None]
        dev = np.where(ok[..., None], theta - mean[block], 0.0)
        cov = block_sum(dev[..., :, None] * dev[..., None, :], starts)
        cov *= ((n - 1.0) / n)[..., None, None]
    return np.where((n > 1)[..., None, None], cov, np.nan)


def pair_azimuth_weights(
    vprime: np.ndarray,
    n_scans: int,
    first_azimuth_deg: np.ndarray,
    dtheta_deg: float,
    sign: float,
    wind_to_deg: np.ndarray,
    n_lags: int = 1,
    valid: FiniteColumns | None = None,
) -> np.ndarray:
    """Weights of the azimuth nodes of the A-table for the pairs of each lag present.

    Each pair of rays ``l`` steps apart with both values valid counts at the angle of the
    block-mean wind's direction of motion from the scan's direction of motion at the
    pair's middle, ``sign (alpha - beta)`` (Smalikho (2020), eq. 15: the wind's component
    along the scan is ``U sin theta``); :func:`cwproc.physics.atable_interp.azimuth_bin_weights`
    shares it between the nodes (summed per node as
    :func:`cwproc.stages.structure.pair_node_weights` sums them, to the bit). The
    azimuth grid of a block is that of its first scan.
    The weights are kept per lag: pairs do not wrap from a scan's last ray to its first,
    so a full circle lacks ``l`` of its ``M`` pair positions at lag ``l``, and where the
    wind makes ``D`` vary strongly with azimuth (``mu`` near 1) the missing positions
    move the mean of ``D(l)`` by several per cent (24-ray VAD, ``mu = 1``, wind fixed to
    the scan start: +3, +5, +7 % at lags 1-3 against the circle mean; exact covariance
    of :mod:`cwproc.sim.exact_gaussian`).

    Parameters
    ----------
    vprime : numpy.ndarray
        ``(scan, m, height)`` deviations V'_L of the blocks.
    n_scans : int
        Scans per block.
    first_azimuth_deg : numpy.ndarray
        ``(block,)`` azimuth of the first ray of each block's first scan (deg).
    dtheta_deg, sign : float
        Azimuth step (deg) and rotation (+1 clockwise).
    wind_to_deg : numpy.ndarray
        ``(block, height)`` direction the mean wind blows towards (deg from north).
    n_lags : int, optional
        Lags l = 1..n_lags.
    valid : FiniteColumns, optional
        :func:`finite_columns` of ``vprime``, if at hand.

    Returns
    -------
    numpy.ndarray
        ``(block, height, n_lags, N_BINS)`` (float32: shares, a quarter of the memory of
        the day's statistics otherwise); NaN where a block, height and lag has no pair.
    """
    starts = np.arange(0, vprime.shape[0], n_scans)
    n_blocks, n_az, n_h = starts.size, vprime.shape[1], vprime.shape[2]
    out = np.full((n_blocks, n_h, n_lags, N_BINS), np.nan, dtype=np.float32)
    lags = min(n_lags, n_az - 1)
    if lags < 1:
        return out
    valid = finite_columns(vprime) if valid is None else valid
    # the pair middles m + l / 2 of every lag l on one grid of half steps j / 2
    m_mid = np.arange(1, 2 * n_az - 2) * 0.5
    beta = first_azimuth_deg[:, None] + sign * dtheta_deg * m_mid[None, :]  # (block, j)
    theta = np.radians(sign * (wind_to_deg[:, None, :] - beta[:, :, None]))
    finite = np.isfinite(theta)
    # each pair shared linearly between its two neighbouring nodes, as pair_node_weights
    pos = _mod_turn(np.where(finite, theta, 0.0)) / (2.0 * np.pi / N_BINS)
    floor = np.floor(pos)
    lower = floor.astype(np.int64)
    lower[lower >= N_BINS] -= N_BINS  # pos is in [0, N_BINS]
    upper = lower + 1
    upper[upper == N_BINS] = 0
    frac = pos - floor
    rest = 1.0 - frac
    # nodes numbered in the (block, height, lag, N_BINS) layout
    cell = (np.arange(n_blocks)[:, None] * n_h + np.arange(n_h)) * (lags * N_BINS)
    # every lag's (block, m, height, lower/upper) nodes and shares, lag after lag
    offsets = np.cumsum([0] + [n_blocks * (n_az - lag) * n_h * 2 for lag in range(1, lags + 1)])
    nodes, shares = np.empty(offsets[-1], dtype=np.int64), np.empty(offsets[-1])
    total = np.empty((n_blocks, n_h, lags))
    all_finite = bool(finite.all())
    for li in range(lags):
        j = slice(li, 2 * n_az - li - 3, 2)  # j = 2 m + l
        n = valid.block_pairs(starts, li + 1)
        if not all_finite:  # a position without a pair shares 0 between its nodes
            n = np.where(finite[:, j], n, 0.0)
        total[..., li] = n.sum(axis=1)
        node = nodes[offsets[li] : offsets[li + 1]].reshape(*n.shape, 2)
        np.add((cell + li * N_BINS)[:, None, :], lower[:, j], out=node[..., 0])
        np.add((cell + li * N_BINS)[:, None, :], upper[:, j], out=node[..., 1])
        share = shares[offsets[li] : offsets[li + 1]].reshape(node.shape)
        np.multiply(rest[:, j], n, out=share[..., 0])
        np.multiply(frac[:, j], n, out=share[..., 1])
    size = n_blocks * n_h * lags * N_BINS  # one sum: each node's shares in m order
    sums = np.bincount(nodes, shares, minlength=size)
    with np.errstate(invalid="ignore", divide="ignore"):
        out[:, :, :lags] = sums.reshape(n_blocks, n_h, lags, N_BINS) / total[..., None]
    return out


def group_median(values: np.ndarray, group: np.ndarray, n_groups: int) -> np.ndarray:
    """Median of the ``values`` (NaN skipped) of each group ``0 .. n_groups - 1`` (NaN: none).

    The middle value, or the mean ``(a + b) / 2`` of the two middle ones, as
    :func:`numpy.median` and pandas' grouped median form it (the same value); the values
    sorted by group once and one partition per group present.
    """
    out = np.full(n_groups, np.nan)
    keep = ~np.isnan(values)
    order = np.argsort(group[keep], kind="stable")
    values, group = values[keep][order], group[keep][order]
    ids, starts = np.unique(group, return_index=True)
    stops = np.append(starts[1:], group.size)[: starts.size]  # none: no group
    for g, start, stop in zip(ids, starts, stops, strict=True):
        out[g] = np.median(values[start:stop])
    return out
