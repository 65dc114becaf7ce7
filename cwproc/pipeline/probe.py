"""The probe volume of the configured lidar, and whether it describes the scans.

The A-functions and the variance correction of the dissipation rate depend on the probe
volume (pulsed range gate or focused cw Lorentzian, Smalikho (2020), eqs. 19-20; Banakh
et al. (1999), eq. 3); these helpers turn the ``[instrument]`` configuration and the scan
dataset's attributes into the physics object and the product attributes recording it.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Literal

import numpy as np
import xarray as xr

from cwproc.config import Config, InstrumentConfig
from cwproc.errors import CwprocError
from cwproc.physics.probe_lengths import ProbeLengths, pulse_rate, pulsed_probe_lengths

if TYPE_CHECKING:
    from cwproc.physics.transfer import Probe


def probe_from_config(
    instrument: InstrumentConfig,
    *,
    pulse_transfer: Literal["physical", "printed"] = "physical",
    data_attrs: Mapping[str, object] | None = None,
) -> Probe:
    """The probe of an instrument configuration and of the data it describes.

    Parameters
    ----------
    instrument : InstrumentConfig
        ``kind == "pulsed"`` gives a ``PulsedProbe`` whose ``Delta_R`` is
        ``delta_r_m`` when set, else the data's range gate length (``gate_length_m``,
        the Stream Line header's ``Range gate length (m)``; 18 m when the data have
        none), and whose ``Delta_p`` is ``delta_p_m`` when set, else the instrument
        model's (Stream Line 15.3 m), Smalikho (2020), eq. 19
        (:func:`cwproc.physics.probe_lengths.pulsed_probe_lengths`);
        ``kind == "cw"`` a ``CWProbe`` from ``beam_radius_m`` and ``wavelength_m`` when
        the beam radius is set, else from ``z_r_coefficient``
        (:mod:`cwproc.physics.transfer`).
    pulse_transfer : {"physical", "printed"}
        Form of the Gaussian term of a pulsed probe (see ``PulsedProbe``).
    data_attrs : mapping, optional
        Attributes of the scan dataset (``gate_length_m``, ``instrument_kind``).

    Raises
    ------
    ValueError
        For ``kind == "sonic"`` (no probe volume) or an impossible parameter.
    """
    from cwproc.physics.transfer import CWProbe, PulsedProbe

    if instrument.kind == "pulsed":
        lengths = pulsed_lengths(instrument, data_attrs)
        return PulsedProbe(lengths.delta_p_m, lengths.delta_r_m, pulse_transfer)
    if instrument.kind == "cw":
        if instrument.beam_radius_m is not None:
            return CWProbe(
                instrument.z_r_coefficient, instrument.wavelength_m, instrument.beam_radius_m
            )
        return CWProbe(instrument.z_r_coefficient)
    raise ValueError(f"instrument kind {instrument.kind!r} has no lidar probe volume")


def pulsed_lengths(
    instrument: InstrumentConfig, data_attrs: Mapping[str, object] | None = None
) -> ProbeLengths:
    """``Delta_p``, ``Delta_R`` (m) and their sources for data with ``data_attrs``."""
    return pulsed_probe_lengths(data_attrs or {}, instrument.delta_p_m, instrument.delta_r_m)


def probe_attrs(config: Config, data_attrs: Mapping[str, object] | None) -> dict[str, object]:
    """Product attributes recording the pulsed probe used (empty for a cw lidar).

    The lengths (:func:`pulsed_lengths`) and the pulse repetition frequency
    (:func:`pulse_rate_hz`) with their sources.
    """
    if config.instrument.kind != "pulsed":
        return {}
    rate = pulse_rate(data_attrs or {}, config.instrument.prf_hz)
    return {**pulsed_lengths(config.instrument, data_attrs).attrs(), **rate.attrs()}


def pulse_rate_hz(config: Config, data_attrs: Mapping[str, object] | None) -> float | None:
    """The PRF (Hz) of a pulsed lidar's data: ``[instrument] prf_hz``, else the model's.

    :func:`cwproc.physics.probe_lengths.pulse_rate`; None for other instruments (their
    rays have no pulses to count).
    """
    if config.instrument.kind != "pulsed":
        return None
    return pulse_rate(data_attrs or {}, config.instrument.prf_hz).prf_hz


def probe_for(config: Config, data_attrs: Mapping[str, object] | None = None) -> Probe:
    """The probe-volume description of the configured instrument (physics object).

    ``data_attrs``: the scan dataset's attributes, which give a pulsed probe its range
    gate length (:func:`probe_from_config`).

    Raises
    ------
    CwprocError
        The configuration describes no lidar (``instrument.kind = "sonic"``).
    """
    if config.instrument.kind not in ("pulsed", "cw"):
        raise CwprocError(
            f"configuration {config.source}: instrument.kind = {config.instrument.kind!r} "
            "describes no lidar probe volume; use a lidar configuration (e.g. -c streamline "
            "or -c zephir300) for scan data"
        )
    return probe_from_config(
        config.instrument, pulse_transfer=config.turbulence.pulse_transfer, data_attrs=data_attrs
    )


def probe_mismatch(scans: xr.Dataset, config: Config) -> str:
    """Why the configured probe cannot describe these scans ('' when it can).

    The A-functions and the variance correction depend on the probe volume (pulsed range
    gate or focused cw Lorentzian, Smalikho (2020), eqs. 19-20; Banakh et al. (1999),
    eq. 3); scans whose ``instrument_kind`` differs from ``[instrument] kind`` would get
    an eps of the wrong instrument (a cw series read with the pulsed default config came
    out 3-25 times too low), so no turbulence product is made for them.
    """
    declared = str(scans.attrs.get("instrument_kind", "")).strip().lower()
    kind = {"streamline": "pulsed", "pulsed": "pulsed", "cw": "cw"}.get(declared)
    if kind is None or kind == config.instrument.kind:
        return ""
    files = ", ".join(str(f) for f in np.atleast_1d(scans.attrs.get("source_files", []))[:3])
    return (
        f"the scans{' of ' + files if files else ''} come from a {kind} lidar "
        f"(instrument_kind = {declared!r}) but configuration {config.source} describes a "
        f"{config.instrument.kind} lidar; use a {kind} configuration "
        f"(e.g. -c {'banakh1999' if kind == 'cw' else 'streamline'})"
    )
