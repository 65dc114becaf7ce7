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
