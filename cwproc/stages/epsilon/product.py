"""The turbulence product of the stage ``epsilon``: the arrays as written, the attributes."""

from __future__ import annotations

from typing import Any

import numpy as np
import xarray as xr

from cwproc.physics.structure_fit import NOISE_CONTRADICTS, NOISE_PLAUSIBLE, NOISE_PRECISION
from cwproc.stages.epsilon.cells import Cells
from cwproc.stages.epsilon.cw_exact import CW_EXACT_MU_MAX
from cwproc.stages.epsilon.flags import METHOD1_RATIO_LIMIT
from cwproc.stages.epsilon.outer_scale import INERTIAL_FRACTION
from cwproc.stages.epsilon.records import CellEstimates


def product_arrays(
    est: CellEstimates, bad: np.ndarray, few_fit: np.ndarray, exact: np.ndarray
) -> dict[str, np.ndarray]:
    """The estimates as written: NaN where flagged bad, never a 0 as measured noise.

    Method 1 is written wherever both estimates exist (its validity is flag 4), with the
    observed ratio ``epsilon_method1 / epsilon`` (Smalikho (2020), eq. 21) and
    ``edr = eps^(1/3)`` (m^(2/3) s-1); the model structure function
    ``eps_fit^(2/3) A_2 + 2 sigma_e^2`` (the exact model's in cw cells).
    """
    e1, efit, noise, a2 = est.e1, est.efit, est.noise, est.a2
    sigma2, l_v, sf_model_exact = est.sigma2, est.l_v, est.sf_model_exact
    eps2 = np.where(bad, np.nan, efit)
    eps1 = np.where(bad, np.nan, e1)
    out_noise = np.where(few_fit | ~(noise > 0), np.nan, noise)
    out_fit = np.where(few_fit | bad, np.nan, efit)
    with np.errstate(invalid="ignore", divide="ignore"):
        observed = eps1 / eps2
    sf_model = out_fit[..., None] ** (2 / 3) * a2 + 2.0 * np.nan_to_num(out_noise)[..., None] ** 2
    sf_model = np.where(
        exact[..., None] & np.isfinite(out_fit)[..., None], sf_model_exact, sf_model
    )
    return {
        "epsilon": eps2,
        "epsilon_method1": eps1,
        "epsilon_ratio": observed,
        "edr": np.cbrt(eps2),
        "epsilon_fit": out_fit,
        "structure_function_model": sf_model,
        "noise_std": out_noise,
        "velocity_variance": np.where(bad | ~(sigma2 > 0), np.nan, sigma2),
        "integral_scale": np.where(bad, np.nan, l_v),
    }


def turbulence_dataset(
    sf: xr.Dataset,
    cells: Cells,
    arrays: dict[str, np.ndarray],
    extra: dict[str, np.ndarray],
    flag: np.ndarray,
) -> xr.Dataset:
    """The product: ``arrays`` (:func:`product_arrays`), ``extra`` ``(time, height)``
    arrays (predicted noise, standard errors), flags, and the sampling geometry
    ``scan_speed``, ``transverse_resolution`` and ``mu`` as auxiliary coordinates (CF).
    """
    dims = ("time", "height")
    return xr.Dataset(
        {
            "structure_function": sf["structure_function"],
            "n_pairs": sf["n_pairs"],
            **{
                k: (("time", "height", "lag") if v.ndim == 3 else dims, v)
                for k, v in arrays.items()
            },
            **{k: (dims, v) for k, v in extra.items()},
            "wind_speed": sf["wind_speed"],
            "n_scans": sf["n_scans"],
            "turbulence_flag": (dims, flag),
        },
        coords={
            **sf.coords,
            "scan_speed": (dims, cells.v_s),
            "transverse_resolution": (dims, cells.dy),
            "mu": (dims, cells.mu),
        },
    )


def describe(out: xr.Dataset, common: dict[str, Any], c_model: float, model: str) -> None:
    """The attributes of the product's estimates: method, references, settings (in place).

    ``common`` (model, lags, ``min_pairs``, probe) goes to the eps estimates;
    ``c_model`` is the ``c`` of ``L_V = c sigma_V^3 / eps`` (Banakh et al. (1999), eq. 19).
    """
    out["epsilon"].attrs.update(
        common,
        method="least squares of Smalikho (2020), eq. 4 over all valid lags with A_2 of "
        "eq. 15 (method 2; eq. 5 is its two-lag case); finite-outer-scale "
        f"A-functions where a length exceeds {INERTIAL_FRACTION:g} L_V; cw cells with "
        f"mu <= {CW_EXACT_MU_MAX:g}: least squares of D_L with the exact B_D of Banakh et "
        "al. (1999), eqs. 15-17, eps = c sigma_V^3 / L_V (eq. 19)",
    )
    out["epsilon_method1"].attrs.update(
        common,
        method="least squares of Smalikho (2020), eq. 4 with A_1 = A_perp (method 1); "
        "written wherever "
        f"computable, flag 4 where eps1/eps2 > {METHOD1_RATIO_LIMIT}",
    )
    out["epsilon_fit"].attrs.update(
        common, method="least squares of eps^(2/3) A_2 + 2 sigma_e^2 over all lags"
    )
    out["structure_function_model"].attrs.update(
        common,
        method="eps_fit^(2/3) A_2(l dy) + 2 sigma_e^2 with the A-functions of the cell "
        "(Smalikho (2020), eq. 4)",
    )
    out["noise_std"].attrs.update(
        method="intercept 2 sigma_e^2 of the least-squares fit, Smalikho (2020), eq. 4, "
        "where its standard error (from the covariance of D over the block's scans) is at "
        f"most {NOISE_PRECISION:g} of the predicted 2 sigma_pred^2 and sigma_e at least "
        f"1/{NOISE_PLAUSIBLE:g} of the predicted one, where it and 2 sigma_pred^2 differ "
        f"by more than {NOISE_CONTRADICTS:g} standard errors of their difference (the "
        "intercept's and the prediction's combined), or where the prediction leaves "
        "no turbulence (without a prediction: where it exceeds twice its standard error); "
        "elsewhere (flag 32) the prediction noise_std_predicted times "
        "noise_std_calibration (where applied), used in the fit; NaN when neither exists"
    )
    out["velocity_variance"].attrs.update(
        method="variance of V'_L minus sigma_e^2 divided by the probe-passed share of "
        "sigma_V^2 (Smalikho (2020), eqs. 16-20; inertial form: plus the averaging loss "
        "eps^(2/3) int int Phi (1 - H_par H_perp)); cw cells: the passed share b_0 less "
        "the share the N-scan VAD fit removes, from the exact B_D"
    )
    out["integral_scale"].attrs.update(
        method=f"L_V = {c_model:.4g} sigma_V^3 / eps",
        correlation_model="exponential (Banakh et al. (1999), eq. 17)"
        if model in ("inertial", "exponential")
        else "von Karman",
    )
