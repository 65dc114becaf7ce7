"""The public Python API (issue 16): ``cwproc.read``, ``retrieve``, ``write``, the
configuration objects built in Python and the ``cwproc.stages`` namespace."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import cwproc
from cwproc.config import config_from_toml
from cwproc.errors import ConfigError, CwprocError, InputFileError
from cwproc.pipeline import retrieve_files

REPO = Path(__file__).resolve().parents[1]
STREAMLINE = REPO / "sample_data" / "streamline"


def assert_same_products(ours: xr.Dataset, written: xr.Dataset) -> None:
    """Same variables and coordinates, equal values (NaN where NaN), same units."""
    assert set(ours.data_vars) == set(written.data_vars)
    for name in list(written.data_vars) + list(written.coords):
        a, b = ours[name], written[name]
        assert a.dims == b.dims, name
        if a.dtype.kind in "fc":
            np.testing.assert_allclose(a.values, b.values, rtol=1e-12, equal_nan=True)
        else:
            np.testing.assert_array_equal(a.values, b.values)
        assert a.attrs.get("units") == b.attrs.get("units"), name


@pytest.fixture(scope="module")
def streamline_result() -> cwproc.Retrieval:
    return cwproc.retrieve(STREAMLINE, "streamline")


def test_every_public_name_resolves_and_import_is_light():
    for name in cwproc.__all__:
        assert getattr(cwproc, name) is not None, name
    code = "import sys, cwproc; print('numpy' in sys.modules, 'xarray' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False"]
    with pytest.raises(AttributeError, match="no_such_name"):
        _ = cwproc.no_such_name


def test_stage_namespace_names_their_own_functions():
    for name in cwproc.stages.__all__:
        value = getattr(cwproc.stages, name)
        assert value.__name__ == name
        assert value.__module__.startswith("cwproc.stages.")
    assert cwproc.stages.qc.__name__ == "cwproc.stages.qc"


def test_retrieve_returns_what_the_command_writes(tmp_path, streamline_result):
    report = retrieve_files(
        sorted(STREAMLINE.glob("*.hpl")), tmp_path, cwproc.load_config("streamline")
    )
    assert report.ok and len(report.written) == 2
    (unit,) = streamline_result.units.values()
    assert sorted(unit.products) == ["turbulence", "wind"]
    for path in report.written:
        name = path.stem.rpartition("_")[2]
        with xr.open_dataset(path) as written:
            assert_same_products(unit.products[name], written)
    assert streamline_result["wind"]["u"].attrs["units"] == "m s-1"
    assert unit.notes and all("conical scan(s)" in n for n in unit.notes)


def test_write_gives_the_files_of_the_command(tmp_path, streamline_result):
    ours = cwproc.write(streamline_result, tmp_path / "api")
    report = retrieve_files(
        sorted(STREAMLINE.glob("*.hpl")), tmp_path / "cli", streamline_result.config
    )
    assert sorted(p.name for p in ours) == sorted(p.name for p in report.written)
    for path in ours:
        with xr.open_dataset(path) as a, xr.open_dataset(tmp_path / "cli" / path.name) as b:
            assert_same_products(a, b)
            assert a.attrs["instrument"] == b.attrs["instrument"] == "Halo Photonics Stream Line"
            assert a.attrs["title"] == b.attrs["title"]


def test_config_built_in_python_equals_the_toml_one(streamline_result):
    text = "[instrument]\nkind = 'cw'\n[vad]\nmin_rays = 8\nmax_gap_deg = 90.0\n"
    from_toml = config_from_toml(text)
    built = cwproc.Config(
        instrument=cwproc.InstrumentConfig(kind="cw"),
        vad=cwproc.VADConfig(min_rays=8, max_gap_deg=90.0),
    )
    assert dataclasses.replace(built, source="<string>") == from_toml
    replaced = cwproc.Config().replace(
        instrument={"kind": "cw"}, vad={"min_rays": 8, "max_gap_deg": 90.0}
    )
    assert dataclasses.replace(replaced, source="<string>") == from_toml
    by_section = cwproc.Config().replace(
        instrument={"kind": "cw"}, vad=cwproc.VADConfig(min_rays=8, max_gap_deg=90.0)
    )
    assert dataclasses.replace(by_section, source="<string>") == from_toml
    assert cwproc.Config.preset("streamline") == cwproc.load_config("streamline")
    assert replaced.source.endswith("(modified)")


def test_python_config_is_validated_like_a_toml_file():
    with pytest.raises(ConfigError, match=r"instrument\.kind: must be one of"):
        cwproc.retrieve(STREAMLINE, cwproc.Config(instrument=cwproc.InstrumentConfig(kind="lidar")))
    with pytest.raises(ConfigError, match=r"vad\.min_rays: must be an integer"):
        cwproc.Config().replace(vad={"min_rays": 6.5})
    with pytest.raises(ConfigError, match=r"vad\.min_ray: unknown key"):
        cwproc.Config().replace(vad={"min_ray": 6})
    with pytest.raises(ValueError, match="min_rays: must be >= 3"):
        cwproc.VADConfig(min_rays=2)


def test_cw_config_on_pulsed_scans_is_an_error_naming_both_instruments():
    """Issue 30.5: a configuration of another kind of lidar than the files' is refused
    (it used to give a wind product and a note on the missing turbulence)."""
    config = cwproc.Config.preset("streamline").replace(instrument={"kind": "cw"})
    with pytest.raises(CwprocError, match=r"VAD_999_.*\.hpl: a file of a pulsed lidar.*cw lidar"):
        cwproc.retrieve(STREAMLINE, config)
    result = cwproc.retrieve(STREAMLINE, config, errors="collect")
    assert not result.ok and not result.units
    assert len(result.failures) == 2


def test_a_bad_input_raises_or_is_collected(tmp_path):
    bad = tmp_path / "VAD_999_20240601_130000.hpl"
    bad.write_bytes((STREAMLINE / "VAD_999_20240601_120000.hpl").read_bytes()[:3000])
    files = [*sorted(STREAMLINE.glob("*.hpl")), bad]
    with pytest.raises(CwprocError, match=str(bad.name)):
        cwproc.retrieve(files, "streamline")
    result = cwproc.retrieve(files, "streamline", errors="collect")
    assert not result.ok
    assert any(bad.name in line for line in result.failures)
    (tmp_path / "empty").mkdir()
    with pytest.raises(CwprocError, match="no input files found"):
        cwproc.retrieve(tmp_path / "empty", "streamline")
    with pytest.raises(CwprocError, match=r"missing\.hpl: cannot read"):
        cwproc.retrieve(tmp_path / "missing.hpl", "streamline")


def test_read_gives_the_canonical_dataset_and_names_a_folder():
    scans = cwproc.read(STREAMLINE / "VAD_999_20240601_120000.hpl")
    assert {"radial_velocity", "snr"} <= set(scans.data_vars)
    assert set(scans["radial_velocity"].dims) == {"ray", "range"}
    same = cwproc.read(STREAMLINE / "VAD_999_20240601_120000.hpl", format="hpl")
    xr.testing.assert_identical(scans, same)
    with pytest.raises(InputFileError, match="not a regular file"):
        cwproc.read(STREAMLINE)


def test_api_page_lists_every_public_name_with_its_signature():
    from cwproc.reference_docs import api_markdown

    page = api_markdown()
    for name in cwproc.__all__:
        if name not in ("__version__", "stages"):
            assert f"### `cwproc.{name}`" in page, name
    for name in cwproc.stages.__all__:
        assert f"### `cwproc.stages.{name}`" in page, name
    assert "cwproc.read(paths: str | os.PathLike | Sequence[str | os.PathLike], *, format" in page
    assert "- `.replace(**sections: Any) -> Config`: A copy with some sections changed" in page


def test_first_day_example_gives_the_products_of_the_command(tmp_path, monkeypatch):
    """docs/examples/first_day.py runs in a fresh folder and its products, in memory
    and written, equal those of ``cwproc retrieve sample_data/streamline -c streamline``."""
    import runpy

    from click.testing import CliRunner

    from cwproc.cli import main

    monkeypatch.chdir(tmp_path)
    namespace = runpy.run_path(str(REPO / "docs" / "examples" / "first_day.py"))
    cli_out = tmp_path / "cli"
    res = CliRunner().invoke(
        main, ["retrieve", str(STREAMLINE), "-c", "streamline", "-o", str(cli_out)]
    )
    assert res.exit_code == 0, res.output
    written = sorted(cli_out.glob("*.nc"))
    assert [p.name.rpartition("_")[2] for p in written] == ["turbulence.nc", "wind.nc"]
    example_files = tmp_path / "first_day_products"
    for path in written:
        name = path.stem.rpartition("_")[2]
        with xr.open_dataset(path) as cli, xr.open_dataset(example_files / path.name) as ours:
            assert_same_products(namespace["result"][name], cli)
            assert_same_products(ours, cli)
    assert (example_files / "wind_profile.png").stat().st_size > 1000
    # the stricter configuration of the example flags more fits, on the same grid
    strict, default = namespace["strict_wind"], namespace["wind"]
    assert strict.sizes == default.sizes
    assert int((strict["qc_flag"] == 0).sum()) < int((default["qc_flag"] == 0).sum())
