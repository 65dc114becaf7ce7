"""The probe comes from the data (issue 29, item 1): Delta_R is the file's range gate
length unless the configuration sets it, Delta_p the instrument model's; the products
record which were used and where they came from."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from cwproc.config import Config, InstrumentConfig
from cwproc.physics.probe_lengths import pulsed_probe_lengths
from cwproc.pipeline import chain, probe_from_config
from cwproc.sim.pulsed import streamline_scans

STREAMLINE = {"instrument_kind": "streamline"}


@pytest.mark.parametrize("gate", [18.0, 30.0, 48.0])
def test_pulsed_probe_takes_the_file_gate(gate):
    probe = probe_from_config(InstrumentConfig(), data_attrs={**STREAMLINE, "gate_length_m": gate})
    assert (probe.delta_r_m, probe.delta_p_m) == (gate, 15.3)


def test_configured_lengths_override_file_and_model():
    lengths = pulsed_probe_lengths(
        {**STREAMLINE, "gate_length_m": 30.0}, delta_p_m=12.0, delta_r_m=24.0
    )
    assert (lengths.delta_r_m, lengths.delta_r_source) == (24.0, "configuration")
    assert (lengths.delta_p_m, lengths.delta_p_source) == (12.0, "configuration")


def test_no_gate_length_falls_back_to_18_m_and_says_so():
    lengths = pulsed_probe_lengths({"gate_length_m": float("nan")})
    assert (lengths.delta_r_m, lengths.delta_r_source) == (18.0, "fallback")
    assert (lengths.delta_p_m, lengths.delta_p_source) == (15.3, "fallback")
    model = pulsed_probe_lengths(STREAMLINE)
    assert (model.delta_p_m, model.delta_p_source) == (15.3, "instrument model")


def _vad_scans(gate_m: float) -> xr.Dataset:
    """Two 36-ray VADs of a uniform wind on 30-m (or ``gate_m``) gates."""
    az = np.tile(np.arange(36) * 10.0, 2)
    ranges = (np.arange(8) + 0.5) * gate_m
    el = np.deg2rad(35.3)
    vr = np.cos(el) * 5.0 * np.cos(np.deg2rad(az - 240.0))[:, None] + 0 * ranges
    vr = vr + 0.05 * np.random.default_rng(3).standard_normal(vr.shape)
    times = np.datetime64("2024-01-01T00:00", "ns") + (np.arange(az.size) * 1e9).astype(
        "timedelta64[ns]"
    )
    return streamline_scans(
        vr,
        times=times,
        azimuth=az,
        elevation_deg=35.3,
        ranges_m=ranges,
        scan=np.repeat([0, 1], 36),
        snr=0.1,
        delta_p_m=15.3,
        delta_r_m=gate_m,
        truth={},
    )


@pytest.mark.parametrize(
    ("config", "expected", "source"),
    [
        (Config(), 30.0, "file"),
        (Config().replace(instrument={"delta_r_m": 18.0}), 18.0, "configuration"),
    ],
)
def test_conical_turbulence_gets_the_file_gate_unless_configured(
    monkeypatch, config, expected, source
):
    """A Stream Line day of 30-m gates is retrieved with Delta_R = 30 m (the probe passed
    to the eps stage and the product's attributes), 18 m only when configured."""
    from cwproc.stages import epsilon, structure

    seen = {}

    def fake_sf(screened, wind, **kwargs):
        return xr.Dataset(coords={"time": wind["time"].values[:1]})

    def fake_eps(sf, *, probe, **kwargs):
        seen["probe"] = probe
        return xr.Dataset()

    monkeypatch.setattr(structure, "azimuth_structure_function", fake_sf)
    monkeypatch.setattr(epsilon, "estimate_epsilon", fake_eps)
    scans = _vad_scans(30.0)
    assert scans.attrs["gate_length_m"] == 30.0
    products = chain.process_scans(scans, config)
    assert seen["probe"].delta_r_m == expected
    assert seen["probe"].delta_p_m == 15.3
    attrs = products["turbulence"].attrs
    assert (attrs["probe_delta_r_m"], attrs["probe_delta_r_source"]) == (expected, source)
    assert attrs["probe_delta_p_source"] == "instrument model"


def test_pulse_rate_from_configuration_model_or_fallback():
    from cwproc.physics.probe_lengths import pulse_rate

    assert pulse_rate(STREAMLINE) == pulse_rate(STREAMLINE, None)
    assert (pulse_rate(STREAMLINE).prf_hz, pulse_rate(STREAMLINE).source) == (
        15000.0,
        "instrument model",
    )
    assert pulse_rate(STREAMLINE, 10000.0).attrs() == {
        "probe_prf_hz": 10000.0,
        "probe_prf_source": "configuration",
    }
    assert pulse_rate({}).source == "fallback"
    with pytest.raises(ValueError, match="prf_hz"):
        InstrumentConfig(prf_hz=0.0)


def test_dwell_is_pulses_over_prf_as_a_fraction_of_the_ray_period():
    from cwproc.physics.probe_lengths import dwell_fraction, ray_dwell_s

    assert ray_dwell_s(15000, 15000.0) == 1.0
    assert ray_dwell_s(None, 15000.0) is None and ray_dwell_s(0, 15000.0) is None
    assert dwell_fraction(1.0, 2.0) == 0.5
    assert dwell_fraction(3.0, 2.0) == 1.0  # rays cannot overlap: the whole period
    assert dwell_fraction(None, 2.0) == 0.0 and dwell_fraction(1.0, float("nan")) == 0.0


def _stare_sf(pulses: int | None) -> xr.Dataset:
    """A structure function's attributes and sampling of a 24-ray step-stare VAD."""
    attrs = {"swept_rays": 0} | ({} if pulses is None else {"pulses_per_ray": pulses})
    return xr.Dataset(
        {
            "scan_period": ("time", np.array([48.0, 48.0, 52.0])),
            "azimuth_step": ("time", np.full(3, 15.0)),
        },
        coords={"height": [100.0, 200.0]},
        attrs=attrs,
    )


@pytest.mark.parametrize(
    ("pulses", "prf", "fraction"), [(15000, None, 0.5), (15000, 10000.0, 0.75), (None, None, 0.0)]
)
def test_step_stare_tables_get_the_dwell_of_the_header(pulses, prf, fraction):
    """The dwell pulses / PRF over the ray period T_scan dtheta / 360 (2 s) goes to the
    A-tables of step-stare rays; swept rays do not take one."""
    from cwproc.stages.epsilon.atable_fit import (
        TableOptions,
        stare_dwell,
        table_height_range,
        table_options_for,
    )

    sf = _stare_sf(pulses)
    options = table_options_for(sf, None, prf)
    assert options.swept is False and options.dwell == pytest.approx(fraction)
    assert stare_dwell(sf, prf)[2] == pytest.approx(2.0)
    swept = sf.assign_attrs(swept_rays=1)
    assert table_options_for(swept, None, prf) == TableOptions(
        table_height_range(swept["height"].values), True
    )


def test_turbulence_product_records_the_dwell_and_the_prf(monkeypatch):
    """The chain passes the instrument model's PRF; the product records it and its source."""
    from cwproc.stages import epsilon, structure

    seen = {}

    def fake_sf(screened, wind, **kwargs):
        return xr.Dataset(coords={"time": wind["time"].values[:1]})

    def fake_eps(sf, *, probe, prf_hz=None, **kwargs):
        seen["prf_hz"] = prf_hz
        return xr.Dataset()

    monkeypatch.setattr(structure, "azimuth_structure_function", fake_sf)
    monkeypatch.setattr(epsilon, "estimate_epsilon", fake_eps)
    products = chain.process_scans(_vad_scans(30.0), Config())
    assert seen["prf_hz"] == 15000.0
    attrs = products["turbulence"].attrs
    assert (attrs["probe_prf_hz"], attrs["probe_prf_source"]) == (15000.0, "instrument model")
    xr_config = Config().replace(instrument={"prf_hz": 10000.0})
    chain.process_scans(_vad_scans(30.0), xr_config)
    assert seen["prf_hz"] == 10000.0
