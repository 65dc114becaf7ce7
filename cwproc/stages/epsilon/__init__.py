"""Dissipation rate, noise, variance and integral scale from D_L (stage ``epsilon``).

Model of the azimuth structure function (Smalikho (2020), eq. 4, generalised by
eqs. 14-15 to wind transport):

.. math::

    \\langle \\bar D_L(l\\Delta\\theta)\\rangle = \\varepsilon^{2/3} A(l\\Delta y) + 2\\sigma_e^2 ,

with ``dy = dtheta R'`` (``R' = h/tan(phi)``) and ``A`` the A-function of the probe
volume (:mod:`cwproc.physics.afunctions`, tabulated by :mod:`cwproc.physics.atable`):

- method 1, ``A = A_1 = A_perp`` (no wind transport, valid for ``mu = U/V_s << 1``);
- method 2, ``A = A_2`` of Smalikho (2020), eq. 15 with ``mu = U/V_s`` and
  ``V_s = 2 pi R'/T_scan`` (Smalikho (2020), eq. 3).

The package holds one module per part: :mod:`~cwproc.stages.epsilon.cells` (statistics
and sampling geometry), :mod:`~cwproc.stages.epsilon.atable_fit` (the A-functions of
methods 1 and 2), :mod:`~cwproc.stages.epsilon.outer_scale` (eps and L_V fitted
together), :mod:`~cwproc.stages.epsilon.cw_exact` (the exact lag model of cw probes),
:mod:`~cwproc.stages.epsilon.errors`, :mod:`~cwproc.stages.epsilon.flags` and
:mod:`~cwproc.stages.epsilon.product`; :func:`estimate_epsilon` runs them. Its defaults
are those of the Stream Line preset (``cwproc/configs/streamline.toml``).

Estimates, per block of scans and height, all vectorised:

- ``epsilon`` (method 2, equal to ``epsilon_fit``) and ``epsilon_method1``: the least
  squares of ``eps^(2/3) A_i(l dy) + 2 sigma_e^2`` over all valid lags ``l = 1..L``
  (:func:`cwproc.physics.structure_fit.fit_structure_function`) with ``A_2`` and
  ``A_1``; Smalikho (2020), eq. 5 is its two-lag case
  (:func:`cwproc.physics.structure_fit.eq5_epsilon`). On exact 24-ray VAD statistics eq. 5 (lags 3
  and 1) scattered 68 % per block against 34 % for the least squares, and its heavy
  tail moved the mean by +8 %; ``epsilon_ratio`` is ``epsilon_method1 / epsilon`` (the
  observed counterpart of eq. 21);
- ``noise_std``: the intercept of that fit, kept where its standard error (from the
  covariance of ``D_L`` over the block's scans) is at most ``NOISE_PRECISION`` of the
  predicted ``2 sigma_pred^2`` and it is at least the prediction over
  ``NOISE_PLAUSIBLE`` squared, where it exceeds the prediction by ``NOISE_CONTRADICTS``
  standard errors, or where the prediction leaves no turbulence
  (:func:`cwproc.physics.structure_fit.fit_structure_function`; never with fewer than
  three lags, a negative value or a prediction below ``NOISE_DETECTABLE``). Elsewhere it
  is fixed at ``2 sigma_pred^2`` of ``noise_std_predicted``
  (:func:`cwproc.stages.epsilon.cells.predicted_noise`, Pearson et al. (2009), eq. 3;
  without a prediction: twice its standard error decides) and flag 32 is set:
  ``noise_std`` is then the prediction, or NaN without one, never a measured 0. The
  prediction is a prior: fit and prediction that differ by more than
  ``NOISE_CONTRADICTS`` standard errors of their difference (both uncertainties) leave
  the data in charge, and the day's free intercepts calibrate the prediction
  (``noise_std_calibration``, :mod:`cwproc.stages.epsilon.noise_prior`), which is then
  the prior where the data do not determine sigma_e;
- ``edr = eps^(1/3)``; standard errors of eps, sigma_V^2 and L_V by the delta method
  through the whole fit (:func:`cwproc.stages.epsilon.errors.covariance_errors`, the
  covariance of ``D_L`` and the variance over the block's scans);
- ``A_1`` and ``A_2`` come from tables of the exact two-beam geometry (any azimuth step,
  :mod:`cwproc.physics.two_beam`, :func:`cwproc.physics.atable.geometry_correction`),
  ``A_2`` averaged over the azimuths of the pairs present (``pair_azimuth_weights``:
  sectors and gaps, :func:`cwproc.stages.epsilon.atable_fit.sector_evaluate`);
- ``velocity_variance``: the variance of ``V'_L`` minus ``sigma_e^2``, divided by the
  part of ``sigma_V^2`` that passes the probe, ``int int Phi_L H_par H_perp /
  int int Phi_L`` with the model's 2-D spectrum at the fitted ``L_V``
  (:func:`cwproc.physics.probe_variance.passed_variance`; Smalikho (2020), eqs. 16-20).
  Where the inertial form is kept (module rule below) the lost part is ``eps^(2/3) int int
  Phi (1 - H_par H_perp)`` with the inertial spectrum of eq. 18
  (:func:`cwproc.physics.probe_variance.averaging_loss`). The inertial loss must
  not be used with a long probe: a cw probe of half width 300 m (h = 500 m, the
  lidar of Banakh et al. (1999)) passes only 25 % of sigma_V^2 of an L_V = 333 m field, and
  the inertial loss overestimated sigma_V^2 2.5-fold, so L_V came out too large and eps 40 % low.
  The share the block-mean VAD wind takes is that of the full circle
  (:func:`cwproc.tables.removed_share.mean_removed_share`), or for sectors and gaps
  (:func:`cwproc.physics.removed_share.partial_circle`) that of the azimuths present
  with the scans' correlation (:func:`cwproc.physics.removed_share.sector_removed_share`);
- ``integral_scale``: ``L_V = c sigma_V^3 / eps``, Banakh et al. (1999), eq. 19, with the
  correlation model named by ``model`` (``c = 1.331`` for the model of Banakh et al.
  (1999), eq. 17, also used with ``model="inertial"``; ``c = 0.697`` for von Kármán).

Finite outer scale (``model="von_karman"`` or ``"exponential"``,
:mod:`cwproc.stages.epsilon.outer_scale`): the inertial-range
A-functions are a limit. ``eps`` and ``L_V`` are fitted together: for every candidate
``L_V`` on a geometric grid over the A-table's outer-scale range (then refined by
bisection), the least squares of eq. 4 with the model's A-functions over all valid lags
gives ``eps(L_V)`` and ``sigma_e(L_V)`` (the two-lag eq. 5 is noisier and, through the
coupling with ``L_V``, biased eps 5 % higher on the simulated cw lidar of Banakh et al. (1999)); the
solution is the largest
``L_V`` at which the variance of ``V'_L`` the model predicts, ``eps^(2/3)`` times
:func:`cwproc.physics.probe_variance.passed_variance` (the probe-passed part of ``(eps L_V /
c)^(2/3)``, Banakh et al. (1999), eq. 19), equals the measured one minus ``sigma_e^2``,
interpolated in ``log L_V``. The rule of the fallback to the inertial form: it is kept where ``L_V``
cannot be determined (no positive corrected variance or no finite ``eps``), where the
root lies above the table's range, and where every length involved -- the largest
separation ``L dy (1 + mu)`` and the probe length ``probe.length_scale_m`` -- is below
2 % of the inertial ``L_V`` (there the finite-scale A-functions differ from the inertial
ones by about 1 % or less); everywhere else the finite-outer-scale A-functions are used.
When even the smallest tabulated ``L_V`` gives too much variance, the lags are beyond
the inertial range (flag 2).

cw probes (finite-outer-scale models, ``mu <= CW_EXACT_MU_MAX``,
:mod:`cwproc.stages.epsilon.cw_exact`): a focused cw probe is
hundreds of metres long at a few hundred metres height, so the structure function's
shape over the lags depends on ``L_V`` and fixes it; the variance condition above, fed
by the sampling error of the variance of ten scans, doubled the scatter of eps there.
These cells use the exact model of Banakh et al. (1999), eqs. 15-17 without transport
(:class:`cwproc.physics.exact_lag.ExactLagModel`: the correlation tensor integrated along
both beams, the transverse spacing varying along the probe): ``D_L(l) = 2 sigma_V^2 [b_0(L_V) -
b_l(L_V)] + 2 sigma_e^2`` fitted by least squares over a grid of ``L_V``
(:func:`cwproc.physics.exact_lag.fit_correlation_shape`), ``eps = c sigma_V^3 / L_V``
(Banakh et al. (1999), eq. 19) from the fitted pair, as in the error study of Banakh et al.
(1999). On three lags the noise is a third parameter, so its variance is pooled (median over
``noise_window_blocks`` neighbouring blocks at a height,
:func:`cwproc.physics.exact_lag.running_nanmedian`) and each block refitted with it fixed.
The variance of ``V'_L`` minus ``sigma_e^2`` then gives ``sigma_V^2`` through ``b_0`` and
the share the N-scan VAD fit removes, ``tr(H B_D)/(N M)``
(:func:`cwproc.physics.exact_lag.hat_trace_per_ray`), and ``L_V = c sigma_V^3 / eps``. The
A-functions at that ``L_V`` still give ``epsilon_method1`` and the ratio.

Flags (``turbulence_flag``, :mod:`cwproc.stages.epsilon.flags`, bits combine; bits 1, 2, 8,
16 make the estimates NaN):

- 1: too few pairs (``n_pairs`` < ``min_pairs`` at lag 1 or lag ``l``): no ``eps``;
- 2: lag beyond the inertial range (Smalikho (2020), after eq. 4): ``L dy (1 + mu) >
  L_V`` with the inertial model; with the finite-outer-scale models (whose A-functions
  hold at any separation) only ``L_V`` below the A-table's range: no ``eps``;
- 4: ``mu`` beyond the validity of method 1, ``eps_1/eps_2 > 1.1`` (Smalikho (2020),
  eq. 21 and its discussion): ``epsilon_method1`` is kept (its bias is the observable of
  eq. 21), ``epsilon`` stays;
- 8: fit failed (``D(l) <= D(1)``, non-finite values, no mean wind for ``mu``, a height
  or ``mu`` outside the A-table's range (the default 10-3000 m height range is widened
  to the data's heights, :func:`cwproc.stages.epsilon.atable_fit.table_height_range`), or
  fewer than two lags within ``max_lag_deg``): no ``eps``;
- 16: partial block: the block holds fewer than half the requested scans per block
  (``n_scans < MIN_BLOCK_FRACTION * n_scans_per_block``, e.g. the 2 scans left over from
  12 scans in blocks of 10): no ``eps``. The variance of ``V'_L`` about the mean of so
  few scans lacks the scan-to-scan variance of the large eddies (the ``N``
  dependence of the errors in the Monte Carlo of Banakh et al. (1999), section 3, repeated
  with the exact eq. 17 model: 33-38 % at N = 1 against 10-12 % at N = 10), so ``L_V``
  and ``eps`` would be biased; half a block keeps the relative error within about 1.5
  times that of a full block (14-16 % at N = 5 in the same Monte Carlo);
- 32: the noise intercept is not determined; the predicted sigma_e is used (above);
- 64: ``L_V`` below the smallest resolved separation ``dy`` (lag 1): the estimates are
  kept but not good (:func:`cwproc.stages.epsilon.flags.unresolved_scale`).

``structure_function_model`` is the fitted ``eps_fit^(2/3) A_2(l dy) + 2 sigma_e^2``
(with the A-functions used for the cell) for plotting against ``structure_function``.
``transverse_resolution`` (dy), ``scan_speed`` (V_s) and ``mu`` (U/V_s) describe the
sampling geometry and regime of each cell and are auxiliary coordinates
``(time, height)`` of the product (CF).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np
import xarray as xr

from cwproc.metadata import described
from cwproc.physics import spectra
from cwproc.physics.constants import STREAMLINE_DELTA_P_M, STREAMLINE_DELTA_R_M
from cwproc.physics.exact_lag import is_cw_probe
from cwproc.physics.spectra import Model
from cwproc.physics.transfer import Probe, PulsedProbe
from cwproc.stages.epsilon.atable_fit import (
    TableOptions,
    cell_a_functions,
    stare_dwell,
    table_options_for,
)
from cwproc.stages.epsilon.cells import cell_inputs, predicted_noise, statistics_covariance
from cwproc.stages.epsilon.cw_exact import NOISE_WINDOW_BLOCKS, apply_exact_cells, exact_cells
from cwproc.stages.epsilon.errors import block_errors, correlated_scans_covariance
from cwproc.stages.epsilon.flags import turbulence_flags
from cwproc.stages.epsilon.noise_prior import (
    NOISE_PRIOR_REL_SE,
    add_calibration,
    calibrated_prior_rel_se,
    calibration_applies,
    cell_intercepts,
    day_calibration,
)
from cwproc.stages.epsilon.outer_scale import fit_cells, fit_setup
from cwproc.stages.epsilon.product import describe, product_arrays, turbulence_dataset
from cwproc.stages.epsilon.records import CellTables, FitMemo, NoisePrior, process_memo

#: the Stream Line preset's probe volume (``cwproc/configs/streamline.toml``:
#: ``pulse_transfer = "physical"``), for data without a range gate length (the pipeline
#: passes the probe of the file's gate, :func:`cwproc.pipeline.probe_for`). The stage
#: reads no configuration: its defaults are literals, equal to the preset's values
#: (``tests/stages/test_epsilon_defaults.py``)
PRESET_PROBE: Probe = PulsedProbe(STREAMLINE_DELTA_P_M, STREAMLINE_DELTA_R_M, "physical")
#: the Stream Line preset's ``[turbulence]`` lag number and spectrum model
PRESET_LAG_NUMBER = 3
PRESET_MODEL: Model = "von_karman"


@described("turbulence")
def estimate_epsilon(
    sf: xr.Dataset,
    *,
    probe: Probe = PRESET_PROBE,
    lag_number: int = PRESET_LAG_NUMBER,
    model: Model = PRESET_MODEL,
    min_pairs: int = 100,
    n_outer_scales: int = 7,
    table_options: dict | None = None,
    fit_noise: bool = True,
    noise_window_blocks: int = NOISE_WINDOW_BLOCKS,
    prf_hz: float | None = None,
) -> xr.Dataset:
    """Dissipation rate (methods 1 and 2), noise, variance and integral scale.

    See the module docstring for the equations, the finite-outer-scale rule and the
    flags. The defaults are those of the Stream Line preset
    (:func:`cwproc.config.load_config` ``("streamline")``).

    Parameters
    ----------
    sf : xarray.Dataset
        Output of :func:`cwproc.stages.structure.azimuth_structure_function`.
    probe : PulsedProbe or CWProbe
        Probe volume (:func:`cwproc.pipeline.probe_for` of a configuration); default
        the Stream Line's pulsed probe (``delta_p_m`` 15.3 m, ``delta_r_m`` 18 m).
    lag_number : int
        l of Smalikho (2020), eq. 5 (>= 2); the largest available lag is used when
        ``l dtheta`` exceeds the structure function's lags (recorded in the attrs).
    model : {"inertial", "von_karman", "exponential"}
        Spectrum model of the A-functions and of L_V (Banakh et al. (1999), eqs. 17, 19).
    min_pairs : int
        Fewest ray pairs at lags 1 and l for an estimate (flag 1 below).
    n_outer_scales : int
        Geometric nodes of L_V scanned for the root of the variance condition
        (finite-outer-scale models) before the bisection refines it.
    table_options : dict, optional
        Keyword arguments of :func:`cwproc.tables.atable.get_a_table` (``cache_dir``,
        ``height_range_m``, ``mu_max``, ``outer_scale_range_m``).
    fit_noise : bool
        Fit the noise term ``2 sigma_e^2`` in the exact cw fit
        (:func:`cwproc.physics.exact_lag.fit_correlation_shape`); without it ``sigma_e``
        is 0 there (noise-free data, e.g. the exact V_D).
    noise_window_blocks : int
        cw fit: the noise variance is the median of the per-block estimates over this
        many neighbouring blocks at the same height
        (:func:`cwproc.physics.exact_lag.running_nanmedian`), and each block refitted
        with it fixed; 1 keeps each block's own estimate.
    prf_hz : float, optional
        Pulse repetition frequency (Hz) of a pulsed lidar: a step-stare ray dwells
        ``pulses_per_ray / prf_hz`` while the wind carries the field, which the A-tables
        average over (:func:`cwproc.stages.epsilon.atable_fit.stare_dwell`); None: the
        Stream Line's 15 kHz. Recorded as ``ray_dwell_s`` and ``ray_dwell_fraction``.

    Returns
    -------
    xarray.Dataset
        Turbulence product (dims ``time``, ``height``, ``lag``).
    """
    if model not in spectra.MODELS:
        raise ValueError(f"unknown model {model!r}; choose one of {', '.join(spectra.MODELS)}")
    if lag_number < 2:
        raise ValueError("lag_number must be >= 2 (Smalikho (2020), eq. 5)")
    options = table_options_for(sf, table_options, prf_hz)  # the A-table of all heights
    settings = BlockGroupSettings(
        probe, lag_number, model, min_pairs, n_outer_scales, options, fit_noise, noise_window_blocks
    )
    # what the groups (and the later days of the process) share: per (dy, range) pair
    memo = process_memo((probe, model, options))
    groups = block_groups(sf, probe)

    def run(prior: tuple[float, float]) -> list[tuple]:
        return [
            _block_group(sf.isel(time=rows), settings, memo=memo, prior=prior) for rows in groups
        ]

    parts = run((1.0, NOISE_PRIOR_REL_SE))
    calibration = day_calibration([p[4] for p in parts])
    applied = calibration_applies(calibration, [p[0] for p in parts])
    if applied:  # the prediction, calibrated, where the data do not determine sigma_e
        parts = run((calibration[0], calibrated_prior_rel_se(calibration)))
    out = parts[0][0] if len(parts) == 1 else _join_blocks([p[0] for p in parts])
    add_calibration(out, calibration, applied)
    finite_used = sum(p[1] for p in parts)
    exact_cells_n = sum(p[2] for p in parts)
    out["integral_scale"].attrs["finite_outer_scale_cells"] = finite_used
    out["integral_scale"].attrs["exact_cw_model_cells"] = exact_cells_n
    common = {
        "model": model,
        "lag_number": int(min(lag_number, sf.sizes["lag"])),
        "lag_number_requested": int(lag_number),
        "min_pairs": int(min_pairs),
        "probe": repr(probe),
    }
    describe(out, common, parts[0][3], model)
    out.attrs.update(dwell_attrs(sf, options, prf_hz))
    return out


def dwell_attrs(sf: xr.Dataset, options: TableOptions, prf_hz: float | None) -> dict[str, Any]:
    """Product attributes of the rays' accumulation: swept, or step-stare with a dwell.

    ``ray_dwell_fraction`` is the dwell over the ray period that the A-tables averaged
    over (rounded to :data:`cwproc.physics.atable.DWELL_STEP`; 1 for swept rays, whose
    rays last their whole period), ``ray_dwell_s`` the dwell pulses per ray / PRF (NaN
    unknown), ``ray_period_s`` the ray period.
    """
    from cwproc.physics.atable import table_dwell_step

    dwell_s, _, tau = stare_dwell(sf, prf_hz)
    if options.swept:
        return {"swept_rays": 1, "ray_dwell_fraction": 1.0, "ray_period_s": tau}
    return {
        "swept_rays": 0,
        "ray_dwell_s": dwell_s,
        "ray_dwell_fraction": table_dwell_step(float(options.dwell)),
        "ray_period_s": tau,
    }


#: cells (block x height) estimated at once where :func:`block_groups` allows it: the
#: model's tables at the cells and the delta-method errors hold arrays of (cell x L_V
#: grid x lag); a day of 192 blocks of 100 heights in groups of 40 blocks peaked 11 MiB
#: lower than at once, for 0.6 s more (the per-(dy, range) tables are made per group)
EPSILON_CELLS = 4096


def block_groups(sf: xr.Dataset, probe: Probe) -> list[slice]:
    """Consecutive blocks estimated together: groups of :data:`EPSILON_CELLS` cells
    where that gives the estimates of all blocks at once, else one group.

    Every estimate is a function of its own block and height, given what the fit
    evaluates once per distinct (dy, range) cell and the median elevation of the
    blocks; the groups give the same when every block has the same elevation, azimuth
    step, ``dy`` and range at each height (the same distinct cells, in the same order),
    the ranges and the scans per block are given (``range``, ``n_scans_per_block``: not
    taken from the group's blocks), and no cell pools over blocks: a cw probe (whose
    exact fit pools the noise over neighbouring blocks, ``noise_window_blocks``) is
    estimated whole.
    """
    n_t, n_h = sf.sizes["time"], sf.sizes["height"]
    step = max(1, EPSILON_CELLS // max(n_h, 1))
    whole = [slice(0, n_t)]
    given = "range" in sf.coords and "n_scans_per_block" in sf["structure_function"].attrs
    if n_t <= step or is_cw_probe(probe) or not given:
        return whole  # else the ranges and the scans a block asks for come from its group
    cells = cell_inputs(sf, probe)
    if not (np.all(np.isfinite(cells.phi)) and np.all(np.isfinite(cells.dtheta))):
        return whole
    for per_block in (cells.phi, cells.dtheta, cells.dy, cells.range_m):
        if not np.array_equal(per_block, np.broadcast_to(per_block[:1], per_block.shape), True):
            return whole
    return [slice(t, min(t + step, n_t)) for t in range(0, n_t, step)]


def _join_blocks(parts: list[xr.Dataset]) -> xr.Dataset:
    """The products of groups of blocks as one (variables without time: the first's),
    its variables in the order of the first."""
    joined = xr.concat(
        parts,
        dim="time",
        data_vars="minimal",
        coords="minimal",
        compat="override",
        join="exact",
        combine_attrs="override",
    )
    return joined[list(parts[0].variables)]


@dataclass(frozen=True)
class BlockGroupSettings:
    """The settings of :func:`estimate_epsilon` every group of blocks is fitted with
    (:func:`_block_group`; each as the parameter of the same name there)."""

    probe: Probe
    lag_number: int
    model: Model
    min_pairs: int
    n_outer_scales: int
    #: the A-table settings (:func:`cwproc.stages.epsilon.atable_fit.table_options_for`)
    options: TableOptions
    fit_noise: bool
    noise_window_blocks: int


def _block_group(
    sf: xr.Dataset,
    settings: BlockGroupSettings,
    *,
    memo: FitMemo | None = None,
    prior: tuple[float, float] = (1.0, NOISE_PRIOR_REL_SE),
) -> tuple[xr.Dataset, int, int, float, tuple]:
    """The turbulence product of the blocks of ``sf`` (:func:`estimate_epsilon`);
    ``memo`` as :func:`cwproc.stages.epsilon.outer_scale.fit_setup`; ``prior``: the
    factor of the predicted sigma_e and the relative standard error of the predicted
    ``2 sigma_e^2`` (:mod:`cwproc.stages.epsilon.noise_prior`).

    Returns the product without its descriptive attributes, the numbers of
    finite-outer-scale and exact cw cells, ``c`` of ``L_V = c sigma_V^3 / eps`` and the
    inputs of the noise calibration (:func:`~cwproc.stages.epsilon.noise_prior.cell_intercepts`).
    """
    probe, model, options = settings.probe, settings.model, settings.options
    cells = cell_inputs(sf, probe)
    lag_used = int(min(settings.lag_number, cells.n_lags))
    valid = cells.pairs >= settings.min_pairs
    noise_raw = predicted_noise(sf, probe)
    noise_pred = noise_raw * prior[0]
    exact = exact_cells(probe, cells, model)
    cov = statistics_covariance(sf)
    setup = fit_setup(
        cells,
        CellTables(*cell_a_functions(probe, cells, model, options)),
        probe=probe,
        model=model,
        options=options,
        valid=valid,
        exact=exact,
        prior=NoisePrior(noise_pred, prior[1]),
        n_outer_scales=settings.n_outer_scales,
        cov=cov,
        memo=memo,
    )
    res = fit_cells(setup, cells.d, cells.var_raw)
    est = dataclasses.replace(res, sf_model_exact=np.full(cells.d.shape, np.nan))
    if np.any(exact):
        est = apply_exact_cells(
            probe,
            cells,
            setup,
            res,
            model,
            options,
            settings.fit_noise,
            settings.noise_window_blocks,
        )
    flag, bad, few_fit = turbulence_flags(cells, valid, lag_used, est, model)
    arrays = product_arrays(est, bad, few_fit, exact)
    cov_errors = correlated_scans_covariance(sf, cells, cov, res.l_v, model)
    eps_se, sigma2_se, scale_se = block_errors(
        sf, lag_used, setup, cells.d, cells.var_raw, arrays, est.noise, res, cov_errors
    )
    out = turbulence_dataset(
        sf,
        cells,
        arrays,
        {
            "noise_std_predicted": noise_raw,
            "epsilon_standard_error": eps_se,
            "velocity_variance_standard_error": sigma2_se,
            "integral_scale_standard_error": scale_se,
        },
        flag,
    )
    intercepts = cell_intercepts(cells, est.a2, valid, setup, noise_raw, bad | exact)
    return out, int(est.finite_used.sum()), int(exact.sum()), setup.c_model, intercepts
