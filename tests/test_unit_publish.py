"""Products: modes from the umask, whole units or nothing (issue 17.6)."""

import os
import stat
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from cwproc.config import Config
from cwproc.errors import ProductError
from cwproc.io import netcdf
from cwproc.pipeline import ProductUnit, write_unit_products


def tiny() -> xr.Dataset:
    t = np.array(["2024-06-01T00:00", "2024-06-01T00:10"], dtype="datetime64[ns]")
    return xr.Dataset({"u": (("time",), [1.0, 2.0])}, coords={"time": t})


@pytest.mark.parametrize("umask", [0o022, 0o002, 0o077])
def test_product_mode_follows_the_umask(tmp_path, umask):
    old = os.umask(umask)
    try:
        path = netcdf.write_netcdf_atomic(tiny(), tmp_path / "p.nc")
    finally:
        os.umask(old)
    assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~umask


def test_a_failing_product_publishes_none_of_its_unit(tmp_path, monkeypatch):
    """Wind written, turbulence failed (a full disk): neither appears, no temporaries."""
    real = netcdf.stage_netcdf
    calls = []

    def failing_second(ds, path, **kw):
        calls.append(path)
        if len(calls) == 2:
            raise ProductError(f"{path}: cannot write product: No space left on device")
        return real(ds, path, **kw)

    monkeypatch.setattr("cwproc.products.writer.stage_netcdf", failing_second)
    unit = ProductUnit(key="streamline_1_20240601", kind="scan")
    with pytest.raises(ProductError, match="No space"):
        write_unit_products(unit, {"wind": tiny(), "turbulence": tiny()}, tmp_path, Config())
    assert list(tmp_path.iterdir()) == []


def test_library_write_error_is_a_product_error(tmp_path, monkeypatch):
    """netCDF4's RuntimeError (e.g. 'HDF error' on a full disk) is not an internal error."""

    def hdf_error(self, *args, **kwargs):
        raise RuntimeError("NetCDF: HDF error")

    monkeypatch.setattr(xr.Dataset, "to_netcdf", hdf_error)
    with pytest.raises(ProductError, match="HDF error"):
        netcdf.write_netcdf_atomic(tiny(), tmp_path / "p.nc")
    assert list(tmp_path.iterdir()) == []


def test_whole_unit_is_published(tmp_path):
    unit = ProductUnit(key="streamline_1_20240601", kind="scan")
    paths = write_unit_products(unit, {"wind": tiny(), "turbulence": tiny()}, tmp_path, Config())
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in paths)
    assert len(paths) == 2


def test_retrieve_removes_stale_temporaries_of_a_killed_run(tmp_path):
    """A killed retrieve left .tmp files no later run removed (issue 14.4, 17.6)."""
    import time as _time

    from cwproc.io.netcdf import STALE_TEMPORARY_S
    from cwproc.pipeline import retrieve_files

    out = tmp_path / "out"
    out.mkdir()
    stale = out / ".streamline_1_20240601_wind.nc.k1ll3d.tmp"
    fresh = out / ".streamline_1_20240601_turbulence.nc.l1v3.tmp"
    for path in (stale, fresh):
        path.write_bytes(b"\x89HDF partial")
    old = _time.time() - STALE_TEMPORARY_S - 10
    os.utime(stale, (old, old))
    report = retrieve_files([], out, Config())
    assert not stale.exists() and fresh.exists()  # a live run's temporary stays
    assert any("interrupted run" in n for n in report.notes)


def test_writers_of_pictures_and_simulated_files_clean_stale_temporaries(tmp_path):
    """plot and simulate (write_hpl) remove what a killed run of theirs left (issue 14.4)."""
    import time as _time

    from cwproc.io.halo import read_hpl, write_hpl
    from cwproc.io.netcdf import STALE_TEMPORARY_S

    stale = tmp_path / ".VAD_1.hpl.dead.tmp"
    stale.write_bytes(b"partial")
    old = _time.time() - STALE_TEMPORARY_S - 10
    os.utime(stale, (old, old))
    sample = next((Path(__file__).parent.parent / "sample_data" / "streamline").glob("*.hpl"))
    write_hpl(read_hpl(sample), tmp_path / "VAD_2.hpl")
    assert not stale.exists()


def test_meteo2_writer_uses_an_unpredictable_temporary_and_cleans_stale_ones(tmp_path):
    """simulate sonic wrote <file>.part (predictable, a planted symlink was followed) and
    left it when killed (issue 17.6, 14.4)."""
    import time as _time

    import numpy as np
    import pandas as pd

    from cwproc.io.meteo2 import read_meteo2, write_meteo2
    from cwproc.io.netcdf import STALE_TEMPORARY_S

    victim = tmp_path / "victim.txt"
    victim.write_text("keep me")
    target = tmp_path / "meteo2_x_20240601.txt"
    (tmp_path / f"{target.name}.part").symlink_to(victim)
    stale = tmp_path / f".{target.name}.dead.tmp"
    stale.write_text("partial")
    old = _time.time() - STALE_TEMPORARY_S - 10
    os.utime(stale, (old, old))
    n = 200
    t = pd.date_range("2024-06-01T12:00", periods=n, freq="100ms").values
    rng = np.random.default_rng(0)
    ds = xr.Dataset(
        {c: ("time", 3.0 + rng.normal(0, 0.5, n)) for c in ("u", "v", "w")},
        coords={"time": t},
    )
    mask = os.umask(0o022)
    try:
        write_meteo2(ds, target, station="x")
    finally:
        os.umask(mask)
    assert victim.read_text() == "keep me"
    assert not stale.exists()
    assert target.stat().st_mode & 0o777 == 0o644
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")) == []
    back = read_meteo2(target)
    assert back.sizes["time"] == n
    assert np.allclose(back["u"].values, ds["u"].values, atol=1e-3)


def test_product_writer_removes_stale_temporaries(tmp_path):
    """write_product (simulate montecarlo --no-png, sf-type) cleans what a killed writer left."""
    import time as _time

    from cwproc.io.netcdf import STALE_TEMPORARY_S
    from cwproc.products.writer import write_product

    stale = tmp_path / ".montecarlo_banakh1999.nc.k1ll3d.tmp"
    stale.write_bytes(b"\x89HDF partial")
    old = _time.time() - STALE_TEMPORARY_S - 10
    os.utime(stale, (old, old))
    write_product(tiny(), tmp_path / "x.nc", product="wind", title="t", summary="s")
    assert not stale.exists()
