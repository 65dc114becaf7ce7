"""The L1 product, the Cloudnet layout and the quality reports end to end (issue 31), on
the shipped Stream Line samples plus a stare of the same day and its cross-polarised
pair written in the real layout; cloudnetpy's own readers on the Cloudnet files."""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
import subprocess
import sys
import venv
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from click.testing import CliRunner

from cwproc.cli import main
from cwproc.io.halo import read_hpl, write_hpl
from cwproc.sim.depol import aerosol_layer, cross_polarised
from cwproc.sim.sample_data import SAMPLE_SPEC
from cwproc.sim.stare import write_stare_series

REPO = Path(__file__).resolve().parents[2]
SITE = REPO / "sample_data" / "site.toml"
KEY = "streamline_999_20240601"
DELTA = 0.2


def run(*args: object):
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)


@pytest.fixture(scope="module")
def day(tmp_path_factory) -> Path:
    """sample_data/streamline (two VAD files, 12:00-12:07) + a 6-min stare from 12:08 of
    the same field, an aerosol layer to 400 m over noise (sd 0.002), and its
    cross-polarised pair (delta 0.2) under the same name in cross/."""
    root = tmp_path_factory.mktemp("cloudnet")
    data, cross = root / "data", root / "cross"
    data.mkdir()
    cross.mkdir()
    for p in sorted((REPO / "sample_data" / "streamline").glob("*.hpl")):
        shutil.copy(p, data)
    spec = dataclasses.replace(SAMPLE_SPEC, start="2024-06-01T12:08:00")
    stare = write_stare_series(root / "sim", root / "truth.json", spec, scan="stare", hours=0.1)[0]
    co = aerosol_layer(read_hpl(stare), top_m=400.0, snr=0.05, noise_std=0.002, seed=1)
    write_hpl(co, data / stare.name)
    write_hpl(cross_polarised(co, DELTA, 0.002, seed=2), cross / stare.name)
    out = root / "out"
    res = run(
        "retrieve",
        data,
        "-c",
        SITE,
        "-o",
        out,
        "--layout",
        "cloudnet",
        "--cross",
        cross,
        "--qc-report",
    )
    assert res.exit_code == 0, res.output
    assert "270 of 270 co-polarised stare rays paired" in res.output
    return root


def test_l1_product_has_beta_depolarisation_and_the_screening(day):
    with xr.open_dataset(day / "out" / f"{KEY}_doppler_lidar.nc") as l1:
        d = l1["depolarisation_screened"].values
        assert np.nanmedian(d) == pytest.approx(DELTA, abs=0.01)
        assert l1["beta"].attrs["units"] == "m-1 sr-1"
        assert "Pentik" in l1["beta_screened"].attrs["references"]
        assert l1["doppler_lidar_flag"].attrs["flag_meanings"].split()[:3] == [
            "near_range",
            "low_snr",
            "velocity_texture",
        ]
        beta = l1["beta_screened"].values
        r = l1["range"].values
        assert np.isnan(beta[:, r < 90]).all()  # near range
        assert np.isfinite(beta[:, (r > 90) & (r < 400)]).mean() > 0.99  # the layer
        assert np.isnan(beta[:, r > 600]).mean() > 0.95  # noise above it
        assert "snr_uncorrected" in l1 and "snr_error" in l1


def test_default_run_writes_no_l1_and_cloudnet_files(day, tmp_path):
    res = run("retrieve", day / "data", "-c", SITE, "-o", tmp_path, "-q")
    assert res.exit_code == 0, res.output
    names = {p.name for p in tmp_path.glob("*.nc")}
    assert names == {f"{KEY}_{n}.nc" for n in ("wind", "turbulence", "stare")}


def test_cross_folder_must_be_a_folder(day, tmp_path):
    res = run("retrieve", day / "data", "-o", tmp_path, "--cross", tmp_path / "nope")
    assert res.exit_code == 2
    assert "--cross" in res.output and "not a folder" in res.output


@pytest.mark.parametrize("name", ["doppler_lidar", "doppler-lidar", "doppler-lidar-wind"])
def test_new_products_are_cf_and_acdd_compliant(day, compliance, name):
    high, acdd = compliance(day / "out" / f"{KEY}_{name}.nc")
    assert not high, high
    assert acdd >= 0.88


def test_quality_report_beside_every_product(day):
    products = sorted((day / "out").glob("*.nc"))
    assert len(products) == 6
    for product in products:
        report = json.loads(product.with_name(product.stem + ".qc.json").read_text())
        tests = {t["testId"]: t["exceptions"] for t in report["tests"]}
        assert set(tests) >= {"TestDataCoverage", "TestCFConvention", "TestACDD", "TestInputs"}
        assert not [e for e in tests["TestCFConvention"] if e["result"] == "error"]
        with xr.open_dataset(product) as ds:
            assert report["fileUuid"] == ds.attrs["file_uuid"]
        # VADs 12:00-12:07 or stares 12:08-12:14: 2 or 3 of the day's 288 5-min bins
        assert 2 / 288 <= report["dataCoverage"] <= 3 / 288
    l1 = json.loads((day / "out" / f"{KEY}_doppler_lidar.qc.json").read_text())
    fractions = l1["flaggedFractions"]["doppler_lidar_flag"]
    assert fractions["near_range"] == pytest.approx(3 / 24)  # 3 of 24 gates below 90 m
    assert fractions["no_cross_ray"] == 0.0


# ---------------------------------------------------------------- cloudnetpy's readers

CLOUDNET_SCRIPT = """
import json, sys
import netCDF4
from cloudnetpy.categorize.lidar import Lidar
from cloudnetpy.products.epsilon_lidar import generate_epsilon_from_lidar
import cloudnetpy
stare, wind, out = sys.argv[1:4]
uuid = generate_epsilon_from_lidar(stare, wind, out)
with netCDF4.Dataset(out) as nc:
    eps = nc["epsilon"][:]
    shape, valid = list(eps.shape), int(eps.count())
    median = float(__import__("numpy").ma.median(eps)) if valid else None
lidar = Lidar(stare)
print(json.dumps({"version": cloudnetpy.__version__, "uuid": str(uuid), "shape": shape,
                  "valid": valid, "median": median,
                  "beta_shape": list(lidar.data["beta"][:].shape),
                  "wavelength": float(lidar.data["lidar_wavelength"].data)}))
"""


def cloudnet_python(cache: Path) -> str:
    """A Python that imports cloudnetpy: $CWPROC_CLOUDNET_PYTHON, this one, or a venv
    (with this environment's packages) made in ``cache`` with ``pip install cloudnetpy``.
    Skips, with pip's reason, when it cannot be installed (no network, no index)."""
    given = os.environ.get("CWPROC_CLOUDNET_PYTHON")
    if given:
        return given
    try:
        import cloudnetpy  # noqa: F401

        return sys.executable
    except ImportError:
        pass
    python = cache / "bin" / "python"
    if not python.exists():
        venv.create(cache, system_site_packages=True, with_pip=True)
    probe = subprocess.run([python, "-c", "import cloudnetpy"], capture_output=True)
    if probe.returncode != 0:
        pip = subprocess.run(
            [python, "-m", "pip", "install", "-q", "cloudnetpy>=1.97"],
            capture_output=True,
            text=True,
            timeout=900,
        )
        if pip.returncode != 0:
            last = (pip.stderr.strip().splitlines() or ["(no output)"])[-1]
            pytest.skip(f"cloudnetpy cannot be installed (pip install cloudnetpy: {last})")
    return os.fspath(python)


@pytest.mark.slow
def test_cloudnetpy_reads_the_cloudnet_files(day):
    """cloudnetpy's epsilon-lidar generator (doppy's O'Connor et al. (2010) on our
    doppler-lidar and doppler-lidar-wind files) and its categorize Lidar reader run on
    cwproc's files unchanged."""
    cache = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "cwproc-cloudnetpy"
    python = cloudnet_python(cache)
    out = day / "out"
    res = subprocess.run(
        [
            python,
            "-c",
            CLOUDNET_SCRIPT,
            out / f"{KEY}_doppler-lidar.nc",
            out / f"{KEY}_doppler-lidar-wind.nc",
            day / "epsilon-lidar.nc",
        ],
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": os.fspath(REPO)},
        timeout=600,
    )
    assert res.returncode == 0, res.stderr[-3000:]
    got = json.loads(res.stdout.strip().splitlines()[-1])
    assert got["shape"] == [270, 24]  # the stare's rays and gates
    assert got["valid"] > 0.3 * 270 * 24  # epsilon where the layer is
    assert got["beta_shape"] == [270, 24]
    assert got["wavelength"] == pytest.approx(1.565e-6)


def test_batch_writes_the_l1_product_and_quality_reports_from_the_configuration(day, tmp_path):
    """cwproc batch (cron) reads the same options from the configuration file."""
    cfg = tmp_path / "site.toml"
    text = SITE.read_text().replace(
        "\n[output]\n", '\n[output]\nlayout = "cloudnet"\nqc_report = true\n'
    )
    cfg.write_text(text + f'\n[doppler_lidar]\nenabled = true\ncross_folder = "{day / "cross"}"\n')
    out = tmp_path / "out"
    res = run("batch", day / "data", out, "--min-age", "0", "-c", cfg)
    assert res.exit_code == 0, res.output
    names = {p.name for p in out.glob("*")}
    for product in ("doppler_lidar", "doppler-lidar", "doppler-lidar-wind", "wind"):
        assert f"{KEY}_{product}.nc" in names and f"{KEY}_{product}.qc.json" in names
    with xr.open_dataset(out / f"{KEY}_doppler_lidar.nc") as l1:
        assert np.nanmedian(l1["depolarisation_screened"].values) == pytest.approx(DELTA, abs=0.01)
