"""Least-squares fits of lg D grown lag by lag from running sums (Gladkikh et al. (2014)).

The structure-function types of :mod:`cwproc.stages.sonic_sf` are decided from a line
(eq. 4), a parabola (eq. 5) and the linear tail of type 3 (eq. 6) fitted in
x = lg(r/r_N), y = lg D_n and grown towards larger lags while the determination
coefficient k_d = 1 - SS_res/SS_tot stays >= k_dL (text after eq. 10). Every fit of
every series and end lag comes from prefix sums of the moments of x and y solved in
closed form, so growing a fit costs no refit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: offsets (in lags) of the candidate starts r_l of the linear part of type 3 beyond r_p:
#: every lag up to 16, then a geometric grid (see :func:`candidate_offsets`)
_DENSE_OFFSETS = 16


@dataclass(frozen=True)
class GrownFit:
    """Result of growing a polynomial fit from a start lag (arrays over series)."""

    #: index of the last lag of the accepted fit; -1 when no fit
    end: np.ndarray
    #: polynomial coefficients (constant first), shape (S, deg + 1); NaN when no fit
    coef: np.ndarray
    #: determination coefficient at ``end``
    kd: np.ndarray


def _prefix(v: np.ndarray) -> np.ndarray:
    """Cumulative sums along the last axis with a leading zero column (NaN counted as 0)."""
    v = np.where(np.isfinite(v), v, 0.0)
    return np.concatenate([np.zeros((*v.shape[:-1], 1)), np.cumsum(v, axis=-1)], axis=-1)


def running_sums(x: np.ndarray, y: np.ndarray, deg: int) -> dict[str, np.ndarray]:
    """Prefix sums of x^p (p <= 2 deg), x^p y (p <= deg), y and y^2 over the lags.

    Parameters
    ----------
    x, y : ndarray, shape (S, K)
        lg r_n and lg D_n; NaN in ``y`` marks an unusable lag.

    Returns
    -------
    dict of ndarray, shape (S, K + 1)
        Key ``"n"`` holds the running count of usable lags.
    """
    ok = np.isfinite(y) & np.isfinite(x)
    xs = np.where(ok, x, 0.0)
    ys = np.where(ok, y, 0.0)
    out = {"n": _prefix(ok.astype(float)), "y": _prefix(ys), "yy": _prefix(ys * ys)}
    for p in range(1, 2 * deg + 1):
        out[f"x{p}"] = _prefix(xs**p)
    for p in range(1, deg + 1):
        out[f"x{p}y"] = _prefix(xs**p * ys)
    return out


def grow_polynomial_fit(
    sums: dict[str, np.ndarray],
    start: np.ndarray,
    deg: int,
    *,
    kd_threshold: float = 0.99850,
    min_points: int = 5,
    series: np.ndarray | None = None,
) -> GrownFit:
    """Grow a least-squares polynomial fit of y(x) from lag ``start`` while k_d >= k_dL.

    For every end lag n >= start + min_points - 1 the fit over lags start..n is solved
    from running sums (no refit loop) and its determination coefficient
    k_d = 1 - SS_res/SS_tot is computed; the fit grows until the first n where
    k_d < k_dL, Gladkikh et al. (2014), eqs. 4-6 and the text after eq. 10.

    Parameters
    ----------
    sums : dict
        Output of :func:`running_sums` with at least degree ``deg``.
    start : ndarray of int, shape (S,)
        First lag index of the fit per series.
    deg : int
        1 (line) or 2 (parabola).
    kd_threshold : float
        k_dL (dimensionless).
    min_points : int
        Fewest lags of a fit (the first tested end is start + min_points - 1).
    series : ndarray of int, shape (S,), optional
        Rows of ``sums`` to fit (default: all, in order).

    Returns
    -------
    GrownFit
    """
    k1 = sums["n"].shape[1]
    series = np.arange(sums["n"].shape[0]) if series is None else np.asarray(series)
    n_series = series.size
    n_lags = k1 - 1
    start = np.asarray(start, dtype=np.int64)
    end = np.full(n_series, -1, dtype=np.int64)
    coef = np.full((n_series, deg + 1), np.nan)
    kd_end = np.full(n_series, np.nan)
    first_test = np.full(n_series, n_lags, dtype=np.int64)
    # ends in blocks of growing width: a series leaves once its fit has failed, so the
    # lags beyond the first failure (most of them) are never computed
    rows = np.arange(n_series)
    lo = min(int(start.min(initial=n_lags)) + min_points - 1, n_lags)
    width = _FIRST_BLOCK
    while rows.size and lo < n_lags:
        hi = min(lo + width, n_lags)
        block = _fit_block(sums, start[rows], series[rows], lo, hi, deg, min_points)
        testable, kd, beta = block
        passed = testable & (kd >= kd_threshold)
        failed = testable & ~passed
        has_test = testable.any(axis=1)
        new_test = has_test & (first_test[rows] == n_lags)
        first_test[rows[new_test]] = lo + np.argmax(testable[new_test], axis=1)
        fails = failed.any(axis=1)
        stop = np.where(fails, np.argmax(failed, axis=1), hi - lo)  # first failure in block
        last = stop - 1  # last end before it, in block columns (-1: the previous block)
        take = last >= 0
        pos = np.flatnonzero(take & (lo + last >= first_test[rows]))
        sel = rows[pos]
        end[sel] = lo + last[pos]
        coef[sel] = beta[pos, last[pos]]
        kd_end[sel] = kd[pos, last[pos]]
        rows = rows[~fails]
        lo, width = hi, 2 * width
    ok = end >= 0
    coef[~ok] = np.nan
    kd_end[~ok] = np.nan
    return GrownFit(end=end, coef=coef, kd=kd_end)


#: width (lags) of the first block of ends of :func:`grow_polynomial_fit` (then doubled)
_FIRST_BLOCK = 48


def _fit_block(
    sums: dict[str, np.ndarray],
    start: np.ndarray,
    rows: np.ndarray,
    lo: int,
    hi: int,
    deg: int,
    min_points: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fits of ``rows`` over lags start..n for the ends n = lo..hi-1 (eqs. 4-6).

    Returns whether each end is testable (at least ``min_points`` lags and deg + 2 usable
    ones), k_d = 1 - SS_res/SS_tot and the coefficients, shapes (R, hi - lo) and
    (R, hi - lo, deg + 1).
    """

    def wsum(key: str) -> np.ndarray:
        c = sums[key]
        return c[rows, lo + 1 : hi + 1] - c[rows, start][:, None]

    cnt = wsum("n")
    sx = [cnt] + [wsum(f"x{p}") for p in range(1, 2 * deg + 1)]
    sxy = [wsum("y")] + [wsum(f"x{p}y") for p in range(1, deg + 1)]
    syy = wsum("yy")
    ends = np.arange(lo, hi)[None, :]
    testable = (ends >= start[:, None] + min_points - 1) & (cnt >= deg + 2)
    with np.errstate(invalid="ignore", divide="ignore"):
        beta = solve_normal_equations(sx, sxy, testable)
    ss_res = syy - sum(beta[..., i] * sxy[i] for i in range(deg + 1))
    with np.errstate(invalid="ignore", divide="ignore"):
        ss_tot = syy - sxy[0] ** 2 / cnt
        kd = 1.0 - ss_res / ss_tot
    return testable, kd, beta


def solve_normal_equations(
    sx: list[np.ndarray], sxy: list[np.ndarray], usable: np.ndarray
) -> np.ndarray:
    """Least-squares polynomial coefficients from moment sums, in closed form.

    Degree 1 or 2 (from ``len(sxy)``); the symmetric normal matrix
    G_ij = sum x^(i+j) is inverted by its adjugate (Cramer's rule), element-wise over
    all series and end lags at once.

    Parameters
    ----------
    sx : list of ndarray
        sum x^p for p = 0..2 deg (p = 0 is the count).
    sxy : list of ndarray
        sum x^p y for p = 0..deg.
    usable : ndarray of bool
        Where a solution is wanted (elsewhere NaN).

    Returns
    -------
    ndarray, shape (..., deg + 1)
        Coefficients, constant first.
    """
    if len(sxy) == 2:
        n, s1, s2 = sx[0], sx[1], sx[2]
        det = n * s2 - s1 * s1
        b1 = (n * sxy[1] - s1 * sxy[0]) / det
        b0 = (sxy[0] - b1 * s1) / n
        out = np.stack([b0, b1], axis=-1)
    else:
        a, b, c, e, f = sx[0], sx[1], sx[2], sx[3], sx[4]
        # G = [[a, b, c], [b, c, e], [c, e, f]]
        c00 = c * f - e * e
        c01 = c * e - b * f
        c02 = b * e - c * c
        c11 = a * f - c * c
        c12 = b * c - a * e
        c22 = a * c - b * b
        det = a * c00 + b * c01 + c * c02
        y0, y1, y2 = sxy
        out = np.stack(
            [
                (c00 * y0 + c01 * y1 + c02 * y2) / det,
                (c01 * y0 + c11 * y1 + c12 * y2) / det,
                (c02 * y0 + c12 * y1 + c22 * y2) / det,
            ],
            axis=-1,
        )
    return np.where(usable[..., None], out, np.nan)


def candidate_offsets(n_lags: int) -> np.ndarray:
    """Offsets (lags) of the candidate starts r_l of the linear part of a type-3 SF.

    Every offset 0..15, then about 24 offsets spaced geometrically up to 0.2 K: the
    type-3 rule Delta_B/Delta_A < 0.25 (Gladkikh et al. (2014), after eq. 6) cannot
    hold for r_l - r_p > 0.2 (r_K - r_min).
    """
    top = max(int(0.2 * n_lags), 1)
    dense = np.arange(min(_DENSE_OFFSETS, top + 1))
    if top <= _DENSE_OFFSETS:
        return dense
    sparse = np.unique(np.rint(np.geomspace(_DENSE_OFFSETS, top, 24)).astype(np.int64))
    return np.unique(np.concatenate([dense, sparse]))


# --------------------------------------------------------------------------------------
# parts of the type decision (rules in decide_types)
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class TypeDecision:
    """Per-series type and fit of :func:`decide_types` (arrays)."""

    sf_type: np.ndarray
    r_max: np.ndarray
    kd: np.ndarray
    line: GrownFit
    parabola: GrownFit
    tail: GrownFit
    r_p: np.ndarray
    r_l: np.ndarray
    type3_ok: np.ndarray


def lag_at(r: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """The lag ``r`` (S, K) at index ``idx`` (S,) of each series; NaN where ``idx`` < 0."""
    safe = np.clip(idx, 0, r.shape[1] - 1)
    return np.where(idx >= 0, r[np.arange(r.shape[0]), safe], np.nan)


def type3_tail(
    r: np.ndarray,
    sums: dict[str, np.ndarray],
    para_end: np.ndarray,
    *,
    kd_threshold: float = 0.99850,
    min_points: int = 5,
) -> tuple[GrownFit, np.ndarray]:
    """The linear part of a type-3 SF from the smallest admissible r_l >= r_p, eq. 6.

    For every candidate offset (:func:`candidate_offsets`) beyond r_p (the end of the
    parabola, index ``para_end``) a line is grown; the first start for which
    Delta_B/Delta_A < 0.25 and r_p - r_min <= r_max - r_l hold (Gladkikh et al. (2014),
    after eq. 6) is kept.

    Returns
    -------
    tail : GrownFit
        The line of each series (``end`` -1 and NaN where none is admissible).
    start : ndarray of int
        Index of r_l per series (-1 where none).
    """
    n_series, n_lags = r.shape
    r_min, r_p = r[:, 0], lag_at(r, para_end)
    tail_end = np.full(n_series, -1)
    tail_start = np.full(n_series, -1)
    tail_coef = np.full((n_series, 2), np.nan)
    tail_kd = np.full(n_series, np.nan)
    searching = (para_end >= 0) & (para_end < n_lags - min_points)
    for off in candidate_offsets(n_lags):
        todo = searching & (tail_end < 0) & (para_end + off <= n_lags - min_points)
        rows = np.flatnonzero(todo)
        if rows.size == 0:
            if not (searching & (tail_end < 0)).any():
                break
            continue
        start = para_end[rows] + off
        fit = grow_polynomial_fit(
            sums, start, 1, kd_threshold=kd_threshold, min_points=min_points, series=rows
        )
        r_sub = r[rows]
        r_l = r_sub[np.arange(rows.size), start]
        r_e = lag_at(r_sub, fit.end)
        rp, rmin = r_p[rows], r_min[rows]
        with np.errstate(invalid="ignore", divide="ignore"):
            accept = (
                (fit.end >= 0)
                & ((r_l - rp) / ((r_e - r_l) + (rp - rmin)) < 0.25)
                & (rp - rmin <= r_e - r_l)
            )
        hit = rows[accept]
        tail_end[hit] = fit.end[accept]
        tail_start[hit] = start[accept]
        tail_coef[hit] = fit.coef[accept]
        tail_kd[hit] = fit.kd[accept]
    return GrownFit(end=tail_end, coef=tail_coef, kd=tail_kd), tail_start


def precedence_type(
    r_max: np.ndarray, flat: np.ndarray, precedence_tolerance: float = 0.05
) -> np.ndarray:
    """The type (1-3, 0: none) among candidates with r_max ``(S, 3)`` (NaN: rejected).

    The simplest type whose lg r_max is within ``precedence_tolerance`` of the largest
    wins; a type 2 whose parabola is ``flat`` falls back to type 1 when the line has an
    r_max (:func:`decide_types`).
    """
    with np.errstate(invalid="ignore", divide="ignore"):
        lg = np.log10(r_max)
    best = np.nanmax(np.where(np.isfinite(lg), lg, -np.inf), axis=1)
    close = np.isfinite(lg) & (lg >= best[:, None] - precedence_tolerance - 1e-12)
    sf_type = np.where(close.any(axis=1), np.argmax(close, axis=1) + 1, 0).astype(np.int8)
    sf_type = np.where((sf_type == 2) & flat & np.isfinite(r_max[:, 0]), 1, sf_type)
    return sf_type.astype(np.int8)


def fit_curves(
    x: np.ndarray, dec: TypeDecision, sf_type: np.ndarray, r_norm: float = 1.0
) -> np.ndarray:
    """lg D_n of the chosen model at every lag (S, K); NaN for type 0.

    The line (eq. 4), the parabola (eq. 5) or, for type 3, the parabola up to
    r_s = (r_p + r_l)/2 and the tail line beyond (eq. 6), Gladkikh et al. (2014).
    """
    lc, pc, tc = dec.line.coef, dec.parabola.coef, dec.tail.coef
    line = lc[:, :1] + lc[:, 1:2] * x
    para = pc[:, :1] + pc[:, 1:2] * x + pc[:, 2:3] * x * x
    tail = tc[:, :1] + tc[:, 1:2] * x
    with np.errstate(invalid="ignore", divide="ignore"):
        x_split = np.log10(np.where(sf_type == 3, 0.5 * (dec.r_p + dec.r_l), np.inf) / r_norm)
        type3 = np.where(x <= x_split[:, None], para, tail)
    out = np.select(
        [sf_type[:, None] == 1, sf_type[:, None] == 2, sf_type[:, None] == 3],
        [line, para, type3],
        np.nan,
    )
    return out


def decide_types(
    r: np.ndarray,
    y: np.ndarray,
    *,
    r_norm: float = 1.0,
    kd_threshold: float = 0.99850,
    precedence_tolerance: float = 0.05,
    min_points: int = 5,
    curvature_tolerance: float = 0.03,
) -> TypeDecision:
    """Type 1, 2 or 3 (or 0) of normalised structure functions, Gladkikh et al. (2014).

    Fits (x = lg(r/r_N), y = lg D_n), all grown from r_min (the first lag) with
    :func:`grow_polynomial_fit`:

    * type 1: line y = b + mu x up to r_max1, eq. 4;
    * type 2: parabola y = a0 + a1 x + a2 x^2 up to r_max2, eq. 5;
    * type 3: the parabola up to r_p = r_max2 (the paper does not say how r_p is
      found: here, the end of the parabola grown from r_min), then a line
      y = c + gamma x grown from the smallest candidate start r_l >= r_p
      (:func:`type3_tail`) for which the type-3 rules of the
      paper hold: Delta_B/Delta_A < 0.25 with Delta_B = r_l - r_p,
      Delta_A = r_max - r_l + r_p - r_min, and r_p - r_min <= r_max - r_l, eq. 6;
      otherwise the SF is type 2 with r_max = r_p.

    A type whose r_max < r_N (1 m) is rejected. Precedence (not stated in the paper,
    whose models are nested): the candidate with the largest r_max wins, except that a
    simpler type (1 < 2 < 3) is taken whenever lg r_max(simpler) >= lg r_max(best) -
    ``precedence_tolerance``; and a type-2 decision falls back to type 1 (with the
    line's own r_max) when the parabola is not significantly curved: its quadratic
    term changes lg D by less than ``curvature_tolerance`` decades over its range,
    |a2| (x_max - x_min)^2 / 8 < curvature_tolerance (the largest departure of a
    parabola from its least-squares line is about that much).

    Parameters
    ----------
    r : ndarray, shape (S, K)
        Lags r_j (m), increasing along the last axis.
    y : ndarray, shape (S, K)
        lg of the normalised structure function; NaN where unusable.
    r_norm : float
        r_N (m).
    kd_threshold : float
        k_dL.
    precedence_tolerance : float
        Tolerance in decades of r_max (see above).
    min_points : int
        Fewest lags in any fit (and in each part of a type-3 fit).
    curvature_tolerance : float
        Decades (see above).

    Returns
    -------
    TypeDecision
    """
    n_series = r.shape[0]
    x = np.log10(r / r_norm)
    sums = running_sums(x, y, 2)
    zero = np.zeros(n_series, dtype=np.int64)
    line = grow_polynomial_fit(sums, zero, 1, kd_threshold=kd_threshold, min_points=min_points)
    para = grow_polynomial_fit(sums, zero, 2, kd_threshold=kd_threshold, min_points=min_points)
    r_p = lag_at(r, para.end)
    tail, tail_start = type3_tail(
        r, sums, para.end, kd_threshold=kd_threshold, min_points=min_points
    )
    # candidates, rejection r_max < r_N, precedence
    r_max = np.stack([lag_at(r, line.end), r_p, lag_at(r, tail.end)], axis=1)  # types 1-3
    r_max = np.where(r_max >= r_norm, r_max, np.nan)
    with np.errstate(invalid="ignore"):
        span = np.log10(r_p / r[:, 0])
        flat = np.abs(para.coef[:, 2]) * span**2 / 8.0 < curvature_tolerance
    sf_type = precedence_type(r_max, flat, precedence_tolerance)
    chosen_rmax = np.where(
        sf_type > 0, r_max[np.arange(n_series), np.clip(sf_type - 1, 0, 2)], np.nan
    )
    kd = np.select(
        [sf_type == 1, sf_type == 2, sf_type == 3],
        [line.kd, para.kd, np.fmin(para.kd, tail.kd)],
        np.nan,
    )
    return TypeDecision(
        sf_type=sf_type,
        r_max=chosen_rmax,
        kd=kd,
        line=line,
        parabola=para,
        tail=tail,
        r_p=r_p,
        r_l=lag_at(r, tail_start),
        type3_ok=tail.end >= 0,
    )
