"""Issue 13 as its users meet it: stare products among the inputs, the stare product's
metadata, usage errors of ``simulate lidar``, background folders, cut-short stare files."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from click.testing import CliRunner

from cwproc.cli import main
from cwproc.io import is_cwproc_product

STARE = "streamline_999_20240101_stare.nc"


def run(*args: object):
    return CliRunner().invoke(main, [str(a) for a in args])


@pytest.fixture(scope="module")
def stares(tmp_path_factory) -> Path:
    """Six minutes of simulated vertical stares (2024-01-01 00:00, 24 gates of 30 m)."""
    root = tmp_path_factory.mktemp("stares")
    result = run("simulate", "lidar", "-o", root, "--scan", "stare", "--hours", "0.1")
    assert result.exit_code == 0, result.output
    return root / "data"


def _background(folder: Path) -> Path:
    """A background file of the hour of the stares (a line in range, 40 gates)."""
    values = 1.7e7 * (1.0 + 1e-5 * (np.arange(40) + 0.5) * 30.0)
    path = folder / "Background_010124-000000.txt"
    path.write_bytes("".join(f"{v:.6f}\r\n" for v in values).encode())
    return path


def test_a_stare_product_among_the_inputs_is_skipped_and_described(stares, tmp_path):
    data = tmp_path / "day"
    shutil.copytree(stares, data)
    args = ("retrieve", data, "-o", data / "products")
    assert run(*args).exit_code == 0
    product = data / "products" / STARE
    assert is_cwproc_product(product)
    second = run(*args)
    assert second.exit_code == 0, second.output
    assert "0 failure(s)" in second.output
    assert "1 cwproc product(s) skipped (not instrument files)" in second.output
    info = run("info", product)
    assert info.exit_code == 0, info.output
    assert "cwproc product (NetCDF, CF-1.10 / ACDD-1.3)" in info.output
    assert "epsilon_stare" in info.output
    hpl = run("info", next(stares.glob("*.hpl")))
    assert "vertical stare ray(s): stare product" in hpl.output


def test_stare_product_says_how_its_snr_was_corrected_and_when_eps_holds(stares, tmp_path):
    data = tmp_path / "day"
    shutil.copytree(stares, data)
    _background(data)
    result = run("retrieve", data, "-o", tmp_path / "out")
    assert result.exit_code == 0, result.output
    assert "corrected with 1 background file(s)" in result.output
    with xr.open_dataset(tmp_path / "out" / STARE) as ds:
        assert ds.attrs["snr_correction"].startswith("Manninen et al. (2016)")
        assert ds.attrs["background_files"] == "Background_010124-000000.txt"
        # CF-1.10 deprecates the 'number_of_observations' modifier
        assert ds["w_n_samples"].attrs["standard_name"] == "number_of_observations"
        comment = ds["epsilon_stare"].attrs["comment"]
        assert "inertial subrange" in comment and "integral scale" in comment


def test_a_background_folder_that_gives_nothing_is_named(stares, tmp_path):
    for folder, said in ((tmp_path / "missing", "is not a folder"), (tmp_path, "no background")):
        config = tmp_path / "bg.toml"
        config.write_text(f'[background]\nfolder = "{folder.as_posix()}"\n', encoding="utf-8")
        result = run("retrieve", stares, "-o", tmp_path / "out", "-c", config)
        assert result.exit_code == 0, result.output
        assert "SNR not corrected: " in result.output and said in result.output
        assert str(folder) in result.output


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--scan", "stare", "--instrument", "cw"], "--scan stare needs --instrument streamline"),
        (["--scan", "mixed", "--instrument", "zephir"], "needs --instrument streamline"),
        (["--vad-every", "5"], "--vad-every is used by --scan mixed only, not --scan vad"),
        (["--scan", "stare", "--vad-every", "5"], "not --scan stare"),
        (["--scan", "mixed", "--vad-every", "0"], "is not in the range x>=1.0"),
        (["--scan", "vertical"], "'vertical' is not one of 'vad', 'stare', 'mixed'"),
    ],
)
def test_simulate_lidar_usage_errors_exit_2(tmp_path, args, message):
    result = run("simulate", "lidar", "-o", tmp_path / "sim", *args)
    assert result.exit_code == 2, result.output
    assert message in result.output
    assert "Traceback" not in result.output
    assert not (tmp_path / "sim").exists()


def test_a_stare_file_cut_mid_line_is_named_as_cut(stares, tmp_path):
    source = next(stares.glob("*.hpl")).read_bytes()
    data = tmp_path / "cut"
    data.mkdir()
    cut = source[: source.index(b"\n", len(source) // 2) + 8]  # 7 bytes into a gate line
    (data / "Stare_999_20240101_000000.hpl").write_bytes(cut)
    result = run("retrieve", data, "-o", tmp_path / "out")
    assert result.exit_code == 1
    line = cut.count(b"\n") + 1
    assert f"Stare_999_20240101_000000.hpl:{line}: gate line has" in result.output
    assert "the file ends inside this line: it was cut short" in result.output
    assert "Traceback" not in result.output


def test_variance_windows_too_short_for_the_ray_rate_are_lengthened_and_named(stares, tmp_path):
    """1-s variance windows of 1.33-s rays would hold one ray: they are lengthened to hold
    4 (a whole number per 300-s window), said in a note and in the product."""
    config = tmp_path / "short.toml"
    config.write_text("[stare]\nvariance_window_s = 1\n", encoding="utf-8")
    result = run("retrieve", stares, "-o", tmp_path / "out", "-c", config)
    assert result.exit_code == 0, result.output
    assert "variance windows of 5.36 s instead of [stare] variance_window_s = 1 s" in (
        result.output
    )
    with xr.open_dataset(tmp_path / "out" / STARE) as ds:
        assert ds.attrs["variance_window_s"] == pytest.approx(300 / 56)
        assert ds.attrs["variance_window_s"] >= 4 * ds.attrs["ray_interval_s"]
        assert np.isfinite(ds["w_variance_corrected"].values).any()


def test_info_names_the_line_of_a_damaged_background_file(tmp_path):
    lines = [f"{1.7e7 + k:.6f}" for k in range(10)]
    lines[5] = "1680x000.5"
    path = tmp_path / "Background_010124-000000.txt"
    path.write_bytes("\r\n".join(lines).encode())
    result = run("info", path)
    assert result.exit_code == 1
    assert f"{path}:6: expected one background value per line, got '1680x000.5'" in result.output
    other = tmp_path / "notes.txt"  # not named as a background file: the sniffer's message
    other.write_bytes(path.read_bytes())
    assert "not a format cwproc reads" in run("info", other).output
