"""Vectorised root search of one rising residual per cell, in ``log L_V`` (numpy only).

The outer-scale fit (:mod:`cwproc.stages.epsilon.outer_scale`) solves one equation per
cell: a residual ``r(L_V)`` of all cells at once, ``(n, k)`` values at ``(n, k)`` outer
scales, whose root is where it rises through zero. :func:`bracket_root` scans nodes,
takes the largest rising sign change and bisects it a fixed number of times (every cell
the same steps, so that one call evaluates all cells); :func:`replayed_root` reaches the
same result near a known root with fewer evaluations, for the many small changes of the
statistics the delta method makes (:mod:`cwproc.stages.epsilon.errors`). Moved here from
``cwproc.stages.epsilon.root_search`` (issue 33).

A bracket is a ``(4, n)`` array ``[log_lo, log_hi, r_lo, r_hi]``; a NaN residual counts
as negative (below the root) throughout.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

#: ``residual(big_l)``: ``(n, k)`` residuals at ``(n, k)`` outer scales (m)
Residual = Callable[[np.ndarray], np.ndarray]


def rising_bracket(nodes: np.ndarray, resid: np.ndarray) -> tuple[np.ndarray, ...]:
    """``(bracket, has_root, below)`` from a scan of ``nodes`` ``(n, k)`` (m).

    The bracket is the largest rising sign change (``r < 0`` then ``r >= 0``) of the
    residuals ``resid`` at the nodes, the last node interval where there is none;
    ``below``: no root and the residual positive at every node.
    """
    sign_change = (resid[:, :-1] < 0) & (resid[:, 1:] >= 0)
    has_root = sign_change.any(axis=1)
    last = nodes.shape[1] - 2 - np.argmax(sign_change[:, ::-1], axis=1)
    cells = np.arange(last.size)
    bracket = np.stack(
        [
            np.log(nodes[cells, last]),
            np.log(nodes[cells, last + 1]),
            resid[cells, last],
            resid[cells, last + 1],
        ]
    )
    return bracket, has_root, ~has_root & np.all(resid > 0, axis=1)


def bisect(residual: Residual, bracket: np.ndarray, steps: int) -> None:
    """``steps`` bisections in ``log L_V`` of every bracket, in place."""
    for _ in range(steps):  # fixed count: each step halves every bracket
        mid = 0.5 * (bracket[0] + bracket[1])
        r_mid = residual(np.exp(mid)[:, None])[:, 0]
        upper = r_mid >= 0
        bracket[1] = np.where(upper, mid, bracket[1])
        bracket[3] = np.where(upper, r_mid, bracket[3])
        bracket[0] = np.where(upper, bracket[0], mid)
        bracket[2] = np.where(upper, bracket[2], r_mid)


def interpolate(bracket: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(root, slope)``: the zero of the residual's chord over the bracket (m) and the
    chord's slope (residual per unit ``log L_V``)."""
    log_lo, log_hi, r_lo, r_hi = bracket
    with np.errstate(invalid="ignore", divide="ignore"):
        frac = np.clip(np.nan_to_num(r_lo / (r_lo - r_hi), nan=0.5), 0.0, 1.0)
        slope = (r_hi - r_lo) / (log_hi - log_lo)
    return np.exp(log_lo + frac * (log_hi - log_lo)), slope


def bracket_root(
    residual: Residual, nodes: np.ndarray, steps: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(root, has_root, below, slope)``: scan of ``nodes`` (m), ``steps`` bisections, chord.

    :func:`rising_bracket`, :func:`bisect` and :func:`interpolate`; ``slope`` is the
    residual's slope by ``log L_V`` over the last bracket (for :func:`replayed_root`).
    """
    bracket, has_root, below = rising_bracket(nodes, residual(nodes))
    bisect(residual, bracket, steps)
    root, slope = interpolate(bracket)
    return root, has_root, below, slope


def _secant_guess(
    residual: Residual, bracket: np.ndarray, x0: np.ndarray, r0: np.ndarray, slope: np.ndarray
) -> np.ndarray:
    """``log L_V`` of the root by a Newton step from ``x0`` with ``slope``, then a secant
    step; a step leaving the bracket falls back to the point it started from (or the
    bracket's middle). One evaluation of ``residual``."""
    lo, hi = bracket[0], bracket[1]
    with np.errstate(invalid="ignore", divide="ignore"):
        x1 = x0 - r0 / slope
    x1 = np.where(np.isfinite(x1) & (x1 > lo) & (x1 < hi), x1, 0.5 * (lo + hi))
    r1 = residual(np.exp(x1)[:, None])[:, 0]
    with np.errstate(invalid="ignore", divide="ignore"):
        x2 = x1 - r1 * (x1 - x0) / (r1 - r0)
    return np.where(np.isfinite(x2) & (x2 > lo) & (x2 < hi), x2, x1)


def replayed_root(
    residual_of: Callable[[np.ndarray], Residual],
    start: np.ndarray,
    slope: np.ndarray,
    factor: float,
    steps: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`bracket_root` over ``start`` times ``1 / factor, 1, factor``, replayed.

    ``(root, has_root, below)`` equal to those of :func:`bracket_root` with ``steps``
    bisections wherever the residual changes sign once in the bracket, from fewer
    evaluations: the root is first located by a Newton and a secant step from
    ``start`` (a root of nearby statistics, m) with its ``slope``; the bisections are
    then replayed without evaluating their midpoints, each going the side of that
    root, and the residual is evaluated only at the two ends they reach. Where those
    contradict the replay (the guess missed the final interval, or the residual jumps
    or turns there) the cell is bisected for real. ``residual_of(index)`` is the
    residual of the cells ``index``. Three evaluations for the ``steps + 1`` of
    :func:`bracket_root`.
    """
    n = start.size
    residual = residual_of(np.arange(n))
    nodes = start[:, None] * np.array([1.0 / factor, 1.0, factor])
    resid = residual(nodes)
    bracket, has_root, below = rising_bracket(nodes, resid)
    guess = _secant_guess(residual, bracket, np.log(start), resid[:, 1], slope)
    replay = bracket.copy()
    moved = np.zeros((2, n), dtype=bool)  # an end replaced by a midpoint
    for _ in range(steps):
        mid = 0.5 * (replay[0] + replay[1])
        upper = mid >= guess
        replay[1] = np.where(upper, mid, replay[1])
        replay[0] = np.where(upper, replay[0], mid)
        moved[1] |= upper
        moved[0] |= ~upper
    at_ends = residual(np.exp(replay[:2].T))
    replay[2] = np.where(moved[0], at_ends[:, 0], replay[2])
    replay[3] = np.where(moved[1], at_ends[:, 1], replay[3])
    # the ends' signs as the bisections would have found them
    agrees = ~(replay[2] >= 0) & (replay[3] >= 0)
    redo = np.flatnonzero(has_root & ~agrees)
    if redo.size:
        again = bracket[:, redo]
        bisect(residual_of(redo), again, steps)
        replay[:, redo] = again
    return interpolate(replay)[0], has_root, below
