"""Averaged tables given where a sonic time series is expected: recognised and refused once.

A logger writes its raw high-rate samples (a Campbell ``ts_data``/``Time_Series`` table of
``Smp`` fields at 10-20 Hz) and, beside them, tables of statistics: 1-, 10- or 30-min
averages, standard deviations, covariances and, with EasyFlux or EddyPro on board, the
fluxes themselves (``Fc_molar``, ``LE``, ``H``, ``Tau``, ``u_star``...). Structure
functions need the samples: a table of statistics read as a "sonic record" of one sample
every 30 min gives "0 lags" in every window. Such a file is refused by its reader with one
line that says what it is and what to give instead (:func:`averaged_table_reason`).

Evidence, any of:

* the processing line of a Campbell TOA5/TOB1 header (line 4) gives a statistic
  (``Avg``, ``Std``, ``Cov``, ``Tot``, ``Max``, ``Min``, ``WVc``, ...) for a wind field,
  where raw tables say ``Smp``;
* flux-result field names (:data:`FLUX_FIELDS`);
* one record per minute or less often (:data:`MIN_AVERAGING_S`), whatever the logger.
"""

from __future__ import annotations

import os

import numpy as np

from cwproc.errors import InputFileError

#: processing words of Campbell statistics (CRBasic output instructions)
STATISTICS = frozenset(
    {"Avg", "Std", "Cov", "Tot", "Max", "Min", "WVc", "Med", "Hst", "Mom", "RMS", "Com"}
)
#: field names of flux results (EasyFlux, EddyPro, OPEC programs): a table holding any of
#: them is a table of interval statistics
FLUX_FIELDS = frozenset(
    {
        "Fc_molar",
        "Fc_mass",
        "Fc",
        "LE",
        "H",
        "Tau",
        "u_star",
        "ET",
        "Rn",
        "TKE",
        "L",
        "MO_LENGTH",
        "H_QC",
        "LE_QC",
        "Fc_QC",
        "Tau_QC",
        "co2_flux",
        "h2o_flux",
    }
)
#: a record interval at least this long (s) is one of statistics, not of samples
MIN_AVERAGING_S = 60.0

#: what to give instead
INSTEAD = "give the raw 10-20 Hz wind samples instead (e.g. the ts_data table, Smp fields)"


def _interval_text(seconds: float) -> str:
    if seconds >= 3600 and seconds % 3600 == 0:
        return f"{seconds / 3600:g}-h"
    if seconds >= 60:
        return f"{seconds / 60:g}-min"
    return f"{seconds:g}-s"


def averaged_table_reason(
    *,
    names: list[str] | None = None,
    processing: list[str] | None = None,
    wind_fields: list[str] | None = None,
    times: np.ndarray | None = None,
) -> str:
    """Why a table is one of statistics ('' when nothing says so).

    Parameters
    ----------
    names : list of str, optional
        Field names of the header.
    processing : list of str, optional
        Campbell processing line (line 4), one word per field.
    wind_fields : list of str, optional
        The fields read as the wind components.
    times : ndarray of datetime64, optional
        The record stamps.

    Returns
    -------
    str
        E.g. ``"statistics: Avg of Ux, Uy, Uz; fluxes Fc_molar, LE, H, Tau"`` or
        ``"30-min statistics: one record every 30-min"``.
    """
    parts = []
    interval = None
    stamps = None if times is None else np.asarray(times).astype("datetime64[ns]")
    if stamps is not None:
        stamps = np.sort(stamps[~np.isnat(stamps)])
    if stamps is not None and stamps.size > 1:
        steps = np.diff(stamps).astype(float) / 1e9
        steps = steps[steps > 0]
        if steps.size:
            interval = float(np.median(steps))
    if names is not None and processing is not None and wind_fields:
        kind = dict(zip(names, processing, strict=False))
        stats = [f for f in wind_fields if kind.get(f, "").strip() in STATISTICS]
        if stats:
            words = sorted({kind[f].strip() for f in stats})
            parts.append(f"{'/'.join(words)} of {', '.join(stats)}")
    if names is not None:
        fluxes = [n for n in names if n in FLUX_FIELDS]
        if fluxes:
            parts.append(f"fluxes {', '.join(fluxes[:4])}")
    if interval is not None and interval >= MIN_AVERAGING_S:
        parts.append(f"a record every {interval / 60:g} min")
    elif not parts:
        return ""
    if interval is not None and interval >= MIN_AVERAGING_S:
        head = f"{_interval_text(interval)} statistics"
    else:
        head = "statistics"
    return f"{head}: {'; '.join(parts)}"


def refuse_averaged_table(path: str | os.PathLike, reason: str) -> None:
    """Raise the one-line refusal of an averaged table (nothing when ``reason`` is '')."""
    if reason:
        raise InputFileError(
            path, f"an averaged table ({reason}), not a sonic time series: {INSTEAD}"
        )
