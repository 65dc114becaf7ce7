"""Typed records of the dissipation-rate fit: its fixed inputs and its estimates per cell.

:class:`FitSetup` is everything :func:`cwproc.stages.epsilon.outer_scale.fit_cells` needs
besides the statistics ``D_L(1..L)`` and the variance of ``V'_L`` of the cells (block x
height), built once per group of blocks by :func:`cwproc.stages.epsilon.outer_scale.fit_setup`
from :class:`CellTables` (the A-functions of the cells) and :class:`NoisePrior` (the
predicted noise term of Smalikho (2020), eq. 4); :class:`CellEstimates` is what the fit
gives. :class:`FitMemo` keeps what depends on the distinct ``(dy, range)`` pairs only
for the next group of blocks of the same probe and model.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cwproc.physics.structure_fit import NOISE_PRIOR_REL_SE

__all__ = [
    "CellEstimates",
    "CellTables",
    "FiniteScaleInputs",
    "FitMemo",
    "FitSetup",
    "NoisePrior",
    "process_memo",
]


@dataclass(frozen=True)
class CellTables:
    """The A-functions of the cells (:func:`cwproc.stages.epsilon.atable_fit.cell_a_functions`).

    Attributes
    ----------
    a1, a2 : numpy.ndarray
        ``(time, height, lag)`` A_perp and A_2 (m^(2/3)) of the inertial tables,
        Smalikho (2020), eqs. 15-16; ``a2`` with the sector ratio applied.
    sector : numpy.ndarray
        ``(time, height, lag)`` the sector ratio of the cells' azimuths (1 for full circles).
    groups : dict
        Configuration key -> ``(rows, (inertial table, model table))``: the blocks of
        each table configuration.
    """

    a1: np.ndarray
    a2: np.ndarray
    sector: np.ndarray
    groups: dict


@dataclass(frozen=True)
class NoisePrior:
    """The predicted noise term of the fit (Smalikho (2020), eq. 4: ``2 sigma_e^2``).

    Attributes
    ----------
    predicted : numpy.ndarray
        ``(time, height)`` the predicted sigma_e (m s-1), calibrated where the day's
        calibration applies (:mod:`cwproc.stages.epsilon.noise_prior`).
    rel_se : float
        Relative standard error of the predicted ``2 sigma_e^2``
        (:func:`cwproc.physics.structure_fit.fit_structure_function`).
    """

    predicted: np.ndarray
    rel_se: float = NOISE_PRIOR_REL_SE


class FitMemo:
    """Arrays kept between groups of blocks, keyed by what they depend on.

    :func:`remembered` computes an array once per key: the averaging loss and the
    passed variance depend on the distinct ``(dy, range)`` pairs only, which are the
    same in every group where :func:`cwproc.stages.epsilon.block_groups` splits a day,
    and in every day of the same scan geometry (:func:`process_memo`). At most
    :data:`MEMO_ARRAYS` arrays are kept (the oldest go first).
    """

    def __init__(self) -> None:
        self._arrays: dict[tuple, np.ndarray] = {}

    def remembered(self, key: tuple, compute: Callable[[], np.ndarray]) -> np.ndarray:
        """``compute()``, kept under ``key`` (whose last item is an array, e.g. of the
        distinct (dy, range) pairs) and taken from the memo for the same key again
        (read-only: it is shared)."""
        *head, pairs = key
        full = (*head, pairs.shape, pairs.tobytes())
        if full not in self._arrays:
            value = np.asarray(compute())
            value.flags.writeable = False
            self._arrays[full] = value
            while len(self._arrays) > MEMO_ARRAYS:
                del self._arrays[next(iter(self._arrays))]
        return self._arrays[full]


#: arrays one :class:`FitMemo` keeps (a day's take a few, of at most a few MB each)
MEMO_ARRAYS = 32
#: :class:`FitMemo` objects :func:`process_memo` keeps (one per probe, model and tables)
PROCESS_MEMOS = 8
_PROCESS_MEMOS: dict[tuple, FitMemo] = {}


def process_memo(scope: tuple) -> FitMemo:
    """The :class:`FitMemo` of ``scope`` (the probe, model and A-table settings of a
    call of :func:`cwproc.stages.epsilon.estimate_epsilon`), kept for the later calls of
    the process: the per-geometry arrays of :func:`cwproc.stages.epsilon.outer_scale.fit_setup`
    (averaging loss, passed variance, transport loss; about 0.15 s a day of 100 heights)
    are then computed once per scan geometry, as the A-tables are loaded once. Keys
    carry everything else the arrays depend on; an unhashable ``scope`` gets a new memo.
    At most :data:`PROCESS_MEMOS` are kept (the least recently used go first).
    """
    try:
        memo = _PROCESS_MEMOS.pop(scope, None)
    except TypeError:  # an unhashable probe: nothing kept
        return FitMemo()
    _PROCESS_MEMOS[scope] = memo = memo or FitMemo()
    while len(_PROCESS_MEMOS) > PROCESS_MEMOS:
        del _PROCESS_MEMOS[next(iter(_PROCESS_MEMOS))]
    return memo


@dataclass(frozen=True)
class FiniteScaleInputs:
    """What the finite-outer-scale fit needs besides D and the variance (per cell).

    Attributes
    ----------
    nodes : numpy.ndarray
        Coarse L_V nodes of the root search (m).
    scale_grid : numpy.ndarray
        Log grid of L_V (m, ratio <= 1.1).
    passed : numpy.ndarray
        ``(time, height, scale)`` probe-passed variance per eps^(2/3) (m^(2/3)), less
        the share the block-mean VAD wind removes.
    full_var : numpy.ndarray
        ``(scale,)`` the full variance per eps^(2/3) (m^(2/3)).
    longest : numpy.ndarray
        ``(time, height)`` the longest length of the cell (m): its largest lag's
        separation or its probe length.
    """

    nodes: np.ndarray
    scale_grid: np.ndarray
    passed: np.ndarray
    full_var: np.ndarray
    longest: np.ndarray


@dataclass(frozen=True)
class FitSetup:
    """Everything :func:`cwproc.stages.epsilon.outer_scale.fit_cells` needs besides ``D``
    and the variance of ``V'_L`` (built by :func:`cwproc.stages.epsilon.outer_scale.fit_setup`).

    Attributes
    ----------
    tables : CellTables
        The A-functions of the cells (``a2`` with the few-ray circles' own).
    valid : numpy.ndarray
        ``(time, height, lag)`` the lags with enough pairs.
    prior : NoisePrior
        The predicted sigma_e and its relative standard error.
    d_cov : numpy.ndarray or None
        ``(time, height, lag, lag)`` covariance of the block means of D_L (m4 s-4).
    loss : numpy.ndarray
        ``(time, height)`` inertial variance lost to the probe and the transport during
        the ray, per eps^(2/3) (m^(2/3)).
    c_model : float
        ``c`` of ``L_V = c sigma_V^3 / eps`` (Banakh et al. (1999), eq. 19).
    cell_tables : dict
        Configuration key -> (the model's table at the group's cells, rank of the rows).
    exact : numpy.ndarray
        ``(time, height)`` the cw cells of the exact model.
    finite : FiniteScaleInputs or None
        The inputs of the variance condition; None for the inertial model.
    """

    tables: CellTables
    valid: np.ndarray
    prior: NoisePrior
    d_cov: np.ndarray | None
    loss: np.ndarray
    c_model: float
    cell_tables: dict
    exact: np.ndarray
    finite: FiniteScaleInputs | None


@dataclass(frozen=True)
class CellEstimates:
    """The estimates of every cell (:func:`cwproc.stages.epsilon.outer_scale.fit_cells`).

    Attributes
    ----------
    a1, a2 : numpy.ndarray
        ``(time, height, lag)`` the A-functions the fit used (m^(2/3)).
    e1, efit : numpy.ndarray
        ``(time, height)`` eps of methods 1 and 2 (m2 s-3).
    noise : numpy.ndarray
        ``(time, height)`` sigma_e (m s-1).
    fitted : numpy.ndarray
        ``(time, height)`` whether sigma_e was fitted (else predicted).
    sigma2, l_v : numpy.ndarray
        ``(time, height)`` sigma_V^2 (m2 s-2) and L_V (m).
    too_small : numpy.ndarray
        ``(time, height)`` even the smallest L_V node gives too much variance.
    finite_used : numpy.ndarray
        ``(time, height)`` the finite-outer-scale fit was used.
    root, root_slope : numpy.ndarray
        ``(time, height)`` its root in L_V (m) and the residual's slope there.
    sf_model_exact : numpy.ndarray or None
        ``(time, height, lag)`` the exact cw model's structure function (m2 s-2), NaN
        elsewhere; None before :func:`cwproc.stages.epsilon.cw_exact.apply_exact_cells`.
    """

    a1: np.ndarray
    a2: np.ndarray
    e1: np.ndarray
    efit: np.ndarray
    noise: np.ndarray
    fitted: np.ndarray
    sigma2: np.ndarray
    l_v: np.ndarray
    too_small: np.ndarray
    finite_used: np.ndarray
    root: np.ndarray
    root_slope: np.ndarray
    sf_model_exact: np.ndarray | None = field(default=None)

    def arrays(self) -> dict[str, Any]:
        """The estimates by name (no copies), as the delta method takes them."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
