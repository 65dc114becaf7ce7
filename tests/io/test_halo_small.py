"""The .hpl reader's dataset assembled directly (issue 35.2): identical to the public
xarray constructor and to ``with_canonical_attrs`` of it, on real and synthetic files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from cwproc.io.halo import read_hpl, write_hpl
from cwproc.io.schema import with_canonical_attrs

REPO = Path(__file__).resolve().parents[2]
REAL_HPL = REPO.parent / "shared" / "real_data" / "hpl"
SAMPLES = sorted((REPO / "sample_data" / "streamline").glob("*.hpl")) + sorted(
    p for p in REAL_HPL.glob("*.hpl") if not p.name.startswith("CORRUPT")
)


def assert_same(a: xr.Dataset, b: xr.Dataset) -> None:
    """Identical values, attributes, variable order, types and indexes."""
    xr.testing.assert_identical(a, b)
    assert list(a.variables) == list(b.variables)
    assert list(a.coords) == list(b.coords) and list(a.xindexes) == list(b.xindexes)
    for name in a.variables:
        va, vb = a.variables[name], b.variables[name]
        assert type(va) is type(vb) and va.dtype == vb.dtype, name
        assert va.attrs.keys() == vb.attrs.keys(), name
        for key in va.attrs:
            np.testing.assert_array_equal(va.attrs[key], vb.attrs[key])
    assert a.sizes == b.sizes and a.attrs == b.attrs


@pytest.mark.parametrize("path", SAMPLES, ids=lambda p: p.name)
def test_direct_assembly_equals_the_public_constructor(path):
    fast = read_hpl(path)
    variables = {
        name: xr.Variable(var.dims, var.values, dict(var.attrs))
        for name, var in fast.variables.items()
    }
    public = xr.Dataset(
        {k: v for k, v in variables.items() if k not in fast.coords},
        coords={k: v for k, v in variables.items() if k in fast.coords},
        attrs=dict(fast.attrs),
    )
    assert_same(fast, public)
    assert_same(fast, with_canonical_attrs(fast, "scan"))  # the attributes it declares


def test_two_reads_share_no_mutable_attribute(tmp_path):
    path = SAMPLES[0]
    a, b = read_hpl(path), read_hpl(path)
    a["scan"].attrs["note"] = "changed"
    a["radial_velocity"].attrs["units"] = "km s-1"
    assert "note" not in b["scan"].attrs
    assert b["radial_velocity"].attrs["units"] == "m s-1"
    assert read_hpl(path)["radial_velocity"].attrs["units"] == "m s-1"


def test_small_file_written_and_read_back_is_exact(tmp_path):
    """A 3-ray stare of 12 gates (the smallest files of an archive) round-trips."""
    t = np.datetime64("2024-06-01T00:00:00", "ns") + np.arange(3) * np.timedelta64(2, "s")
    rng = np.random.default_rng(3)
    ds = xr.Dataset(
        {
            "radial_velocity": (("ray", "range"), np.round(rng.normal(0, 1, (3, 12)), 4)),
            "snr": (("ray", "range"), np.round(rng.uniform(0.01, 1, (3, 12)), 6)),
            "beta": (("ray", "range"), np.round(rng.uniform(1e-7, 1e-5, (3, 12)), 12)),
        },
        coords={
            "time": ("ray", t),
            "azimuth": ("ray", np.zeros(3)),
            "elevation": ("ray", np.full(3, 90.0)),
            "range": ("range", (np.arange(12) + 0.5) * 30.0),
        },
        attrs={"system_id": "7", "scan_type": "Stare", "gate_length_m": 30.0},
    )
    back = read_hpl(write_hpl(ds, tmp_path / "Stare_7_20240601_00.hpl"))
    assert back.sizes == {"ray": 3, "range": 12}
    for name in ("radial_velocity", "snr", "beta"):
        np.testing.assert_allclose(back[name].values, ds[name].values, rtol=1e-6, atol=1e-12)
    # decimal hours as Stream Line writes them: within 0.01 s
    assert np.abs(back["time"].values - t).max() < np.timedelta64(10, "ms")
    assert back["range"].attrs["units"] == "m"
