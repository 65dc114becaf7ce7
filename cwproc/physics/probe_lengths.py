"""Pulse and range-gate lengths of a pulsed lidar's probe, and where each came from.

The range weighting of a pulsed coherent Doppler lidar is a Gaussian pulse of half
width ``Delta_p = c sigma_p / 2`` convolved with the range window (gate) of length
``Delta_R = c T_w / 2`` (Smalikho (2020), eq. 19). ``Delta_R`` is a setting of every
measurement: the Stream Line writes it in each file's header (``Range gate length (m)``)
together with the number of digitiser points per gate (``Gate length (pts)``); with the
digitiser's sampling frequency ``f_s``, ``T_w = points / f_s`` and ``Delta_R = points x
c / (2 f_s)``: 3 m per point at 50 MHz (the files of most Stream Lines), 1.5 m at
100 MHz. The header's metres are used as written, never derived from the points (the
sampling frequency is not in the file). ``Delta_p`` is a property of the laser, so it
comes from the instrument model (:data:`PULSE_HALF_WIDTH_M`).

Precedence: a value set in the configuration, then the file (``Delta_R``) or the
instrument model (``Delta_p``), then the Stream Line values of Smalikho (2020) as a
fallback, recorded as such.

A step-stare ray holds its azimuth while it accumulates its pulses: it dwells ``T_d =
pulses per ray / PRF`` (:func:`ray_dwell_s`; the Stream Line header has ``Pulses/ray``,
the pulse repetition frequency is a setting of the instrument model,
:data:`PULSE_REPETITION_HZ`, with the same precedence), a fraction ``d = T_d / tau`` of
the ray period ``tau`` (:func:`dwell_fraction`), while the mean wind carries the field
past (:func:`cwproc.physics.atable_swept.dwell_kernel`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from cwproc.physics.constants import STREAMLINE_DELTA_P_M, STREAMLINE_DELTA_R_M

#: pulse half width Delta_p = c sigma_p / 2 (m) per instrument model (the scan dataset's
#: ``instrument_kind``): Stream Line 15.3 m, Smalikho (2020), after eq. 19
PULSE_HALF_WIDTH_M: dict[str, float] = {"streamline": STREAMLINE_DELTA_P_M}
#: Delta_R (m) when neither the configuration nor the file gives it: the 18 m gate of the
#: measurements of Smalikho (2020)
FALLBACK_DELTA_R_M = STREAMLINE_DELTA_R_M
#: pulse repetition frequency (Hz) per instrument model: the Stream Line's 15 kHz (Halo
#: Photonics; the long-range Stream Line XR fires at 10 kHz: set ``[instrument] prf_hz``)
PULSE_REPETITION_HZ: dict[str, float] = {"streamline": 15000.0}
#: the PRF when neither the configuration nor the instrument model gives it (Stream Line)
FALLBACK_PRF_HZ = 15000.0

SOURCE_CONFIG = "configuration"
SOURCE_FILE = "file"
SOURCE_MODEL = "instrument model"
SOURCE_FALLBACK = "fallback"


@dataclass(frozen=True)
class ProbeLengths:
    """``Delta_p`` and ``Delta_R`` (m) of a pulsed probe and the source of each.

    Sources: ``"configuration"`` (set by the user), ``"file"`` (the range gate length
    of the data), ``"instrument model"`` (:data:`PULSE_HALF_WIDTH_M`), ``"fallback"``
    (the Stream Line values of Smalikho (2020): the data did not say).
    """

    delta_p_m: float
    delta_p_source: str
    delta_r_m: float
    delta_r_source: str

    def attrs(self, prefix: str = "probe_") -> dict[str, float | str]:
        """The product attributes that record the probe (``probe_delta_r_m``, ...)."""
        return {
            f"{prefix}delta_p_m": float(self.delta_p_m),
            f"{prefix}delta_p_source": self.delta_p_source,
            f"{prefix}delta_r_m": float(self.delta_r_m),
            f"{prefix}delta_r_source": self.delta_r_source,
        }


def _positive(value: object) -> float | None:
    """``value`` as a finite positive float, else None."""
    try:
        x = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) and x > 0 else None


def pulsed_probe_lengths(
    attrs: Mapping[str, object],
    delta_p_m: float | None = None,
    delta_r_m: float | None = None,
) -> ProbeLengths:
    """The probe lengths of pulsed-lidar data (Smalikho (2020), eq. 19).

    Parameters
    ----------
    attrs : mapping
        Attributes of the scan dataset: ``gate_length_m`` (the header's ``Range gate
        length (m)``) and ``instrument_kind``.
    delta_p_m, delta_r_m : float or None
        Values set in the configuration (m); ``None``: from the instrument model and the
        file.

    Returns
    -------
    ProbeLengths
        ``Delta_R`` = ``delta_r_m`` if set, else the file's gate length, else 18 m
        (``"fallback"``); ``Delta_p`` = ``delta_p_m`` if set, else the model's value,
        else 15.3 m (``"fallback"``).
    """
    if delta_r_m is not None:
        dr, dr_source = float(delta_r_m), SOURCE_CONFIG
    elif (gate := _positive(attrs.get("gate_length_m"))) is not None:
        dr, dr_source = gate, SOURCE_FILE
    else:
        dr, dr_source = FALLBACK_DELTA_R_M, SOURCE_FALLBACK
    kind = str(attrs.get("instrument_kind", "")).strip().lower()
    if delta_p_m is not None:
        dp, dp_source = float(delta_p_m), SOURCE_CONFIG
    elif kind in PULSE_HALF_WIDTH_M:
        dp, dp_source = PULSE_HALF_WIDTH_M[kind], SOURCE_MODEL
    else:
        dp, dp_source = STREAMLINE_DELTA_P_M, SOURCE_FALLBACK
    return ProbeLengths(dp, dp_source, dr, dr_source)


@dataclass(frozen=True)
class PulseRate:
    """Pulse repetition frequency (Hz) of a pulsed lidar and its source (:class:`ProbeLengths`)."""

    prf_hz: float
    source: str

    def attrs(self, prefix: str = "probe_") -> dict[str, float | str]:
        """The product attributes (``probe_prf_hz``, ``probe_prf_source``)."""
        return {f"{prefix}prf_hz": float(self.prf_hz), f"{prefix}prf_source": self.source}


def pulse_rate(attrs: Mapping[str, object], prf_hz: float | None = None) -> PulseRate:
    """The PRF of the data: ``prf_hz`` if set, else the instrument model's, else 15 kHz."""
    if prf_hz is not None:
        return PulseRate(float(prf_hz), SOURCE_CONFIG)
    kind = str(attrs.get("instrument_kind", "")).strip().lower()
    if kind in PULSE_REPETITION_HZ:
        return PulseRate(PULSE_REPETITION_HZ[kind], SOURCE_MODEL)
    return PulseRate(FALLBACK_PRF_HZ, SOURCE_FALLBACK)


def ray_dwell_s(pulses_per_ray: object, prf_hz: float) -> float | None:
    """Dwell ``T_d = pulses / PRF`` (s) of a ray; None when the pulses per ray are unknown."""
    pulses = _positive(pulses_per_ray)
    rate = _positive(prf_hz)
    return None if pulses is None or rate is None else pulses / rate


def dwell_fraction(dwell_s: float | None, ray_period_s: float) -> float:
    """``d = T_d / tau`` in ``[0, 1]``: 0 when either is unknown (instantaneous rays).

    A dwell longer than the ray period (timestamps of a file whose rays overlap, or a
    wrong PRF) is the whole period.
    """
    period = _positive(ray_period_s)
    if dwell_s is None or period is None or not math.isfinite(dwell_s):
        return 0.0
    return float(min(1.0, max(0.0, dwell_s / period)))
