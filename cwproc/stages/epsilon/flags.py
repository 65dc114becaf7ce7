"""Flag bits of ``turbulence_flag`` and the rules that set them (stage ``epsilon``).

Bits combine; 1, 2, 8 and 16 make the estimates NaN (the list is in the docstring of
:mod:`cwproc.stages.epsilon`); 64 keeps them but marks them not good.
"""

from __future__ import annotations

import numpy as np

from cwproc.stages.epsilon.cells import Cells
from cwproc.stages.epsilon.records import CellEstimates

#: turbulence_flag bits
FLAG_TOO_FEW_PAIRS = 1
FLAG_BEYOND_INERTIAL = 2
FLAG_METHOD1_INVALID = 4
FLAG_FIT_FAILED = 8
FLAG_PARTIAL_BLOCK = 16
FLAG_NOISE_PREDICTED = 32
#: L_V below the smallest resolved separation (dy at lag 1), or a fit that needs it
FLAG_UNRESOLVED_SCALE = 64
#: the bits that make the estimates NaN
FLAGS_BAD = FLAG_TOO_FEW_PAIRS | FLAG_BEYOND_INERTIAL | FLAG_FIT_FAILED | FLAG_PARTIAL_BLOCK

#: a block with fewer than this share of the requested scans is not estimated (flag 16)
MIN_BLOCK_FRACTION = 0.5

#: eps_1/eps_2 above which method 1 is not used (Smalikho (2020), eq. 21: 10 % bias)
METHOD1_RATIO_LIMIT = 1.1


def _bit(condition: np.ndarray, bit: int) -> np.ndarray:
    """``bit`` where ``condition`` holds, else 0 (int16)."""
    return np.where(condition, bit, 0).astype(np.int16)


def turbulence_flags(
    cells: Cells, valid: np.ndarray, lag_used: int, est: CellEstimates, model: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(flag, bad, few_fit)`` of every cell ``(time, height)``.

    Parameters
    ----------
    cells : Cells
        Statistics and sampling geometry.
    valid : numpy.ndarray of bool
        ``(time, height, lag)`` lags with enough pairs.
    lag_used : int
        The lag ``l`` of Smalikho (2020), eq. 5 (flag 1 needs pairs at lags 1 and l;
        the ratio of eq. 21 is taken between them).
    est : CellEstimates
        The estimates (``a1``, ``a2``, ``efit``, ``l_v``, ``too_small``, ``fitted``).
    model : str
        Spectrum model; with ``"inertial"`` the largest separation ``L dy (1 + mu)``
        must stay below ``L_V`` (flag 2, Smalikho (2020), after eq. 4).

    Returns
    -------
    (flag, bad, few_fit) : numpy.ndarray
        The int16 flags, the cells whose estimates are NaN (bits in :data:`FLAGS_BAD`)
        and those with fewer than two valid lags.
    """
    n_l = cells.n_lags
    a1, a2, l_v = est.a1, est.a2, est.l_v
    partial = cells.scans < MIN_BLOCK_FRACTION * cells.requested
    flag = np.zeros(l_v.shape, dtype=np.int16)
    flag |= _bit(partial[:, None], FLAG_PARTIAL_BLOCK)
    flag |= _bit(~(valid[..., 0] & valid[..., lag_used - 1]), FLAG_TOO_FEW_PAIRS)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = ((a2[..., lag_used - 1] - a2[..., 0]) / (a1[..., lag_used - 1] - a1[..., 0])) ** 1.5
    # inertial form: the largest separation L dy (1 + mu) must stay below L_V (Smalikho
    # (2020), after eq. 4). The finite-outer-scale A-functions hold at any separation: a
    # limit on the fitted L_V there only dropped the blocks whose sampling error made
    # L_V small (eps high), and biased the mean eps of 24-ray VADs 8-16 % low
    beyond = est.too_small
    if model == "inertial":
        beyond = beyond | (np.isfinite(l_v) & (n_l * cells.dy * (1 + cells.mu_eval) > l_v))
    flag |= _bit(beyond, FLAG_BEYOND_INERTIAL)
    failed = ~np.isfinite(est.efit) | ~np.isfinite(cells.mu) | (n_l < 2)
    flag |= _bit(failed, FLAG_FIT_FAILED)
    bad = (flag & FLAGS_BAD) > 0
    flag |= _bit(~(ratio <= METHOD1_RATIO_LIMIT) & ~bad, FLAG_METHOD1_INVALID)
    few_fit = valid.sum(axis=-1) < 2
    flag |= _bit(~est.fitted & ~few_fit & ~bad, FLAG_NOISE_PREDICTED)
    flag |= _bit(unresolved_scale(l_v, cells.dy) & ~bad, FLAG_UNRESOLVED_SCALE)
    return flag, bad, few_fit


def unresolved_scale(l_v: np.ndarray, dy: np.ndarray, smallest_lag: int = 1) -> np.ndarray:
    """Cells whose L_V (m) lies below the smallest separation the scan resolves (flag 64).

    The smallest separation of the structure function is ``smallest_lag dy`` (``dy =
    dtheta R'``, Smalikho (2020), eq. 3): an eddy scale below it is not sampled, so an
    ``L_V = c sigma_V^3 / eps`` (Banakh et al. (1999), eq. 19) there is an extrapolation
    of the model beyond its data -- the heavy upper tail of eps on coarse scans (single
    24-ray blocks 12 times the truth with L_V of 20-80 m). The estimates are kept (a
    limit that drops them biases the mean eps low, see :func:`turbulence_flags`) but are
    not good.
    """
    with np.errstate(invalid="ignore"):
        return np.isfinite(l_v) & np.isfinite(dy) & (l_v < smallest_lag * np.abs(dy))
