"""``cwproc retrieve`` and ``cwproc batch`` run one chain (``pipeline.run_unit``), so on the
same inputs they give the same products, the same notes and the same exit status (issue 16).

The inputs are the shipped Stream Line sample files (two VAD files of one day, a pulsed
lidar) with three configurations:

- ``streamline``: the instrument's own preset; wind and turbulence, exit status 0;
- ``banakh1999``: a cw preset that reads cw scan NetCDF only; every file is named with
  the reason it is skipped, nothing is made, exit status 1 in both (before: ``retrieve``
  stopped with a usage error, ``batch`` counted two unrecognised files and exited 0);
- ``zephir300``: a cw preset that reads any format; the wind (independent of the probe
  volume) is made, turbulence is not, with a note naming the files and the cw/pulsed
  mismatch (Smalikho (2020), eqs. 19-20 hold for the pulsed range gate only), exit 0.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import xarray as xr
from click.testing import CliRunner

from cwproc.cli import main
from cwproc.io.netcdf import read_product

SAMPLES = Path(__file__).resolve().parents[1] / "sample_data" / "streamline"


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> Path:
    """The two sample Stream Line files in a folder of their own (absolute path)."""
    folder = tmp_path_factory.mktemp("parity") / "in"
    folder.mkdir()
    for path in sorted(SAMPLES.glob("*.hpl")):
        shutil.copy(path, folder / path.name)
    return folder.absolute()


def run(args: list[str]) -> tuple[int, set[str], set[str]]:
    """Exit status, note lines and failure lines (stderr) of one command."""
    res = CliRunner().invoke(main, args)
    assert res.exception is None or isinstance(res.exception, SystemExit), res.output
    lines = res.stderr.splitlines()
    notes = {line.removeprefix("note: ") for line in lines if line.startswith("note: ")}
    errors = {line.removeprefix("error: ") for line in lines if line.startswith("error: ")}
    return res.exit_code, notes, errors


def products(folder: Path) -> dict[str, xr.Dataset]:
    """``{file name: dataset}`` of the products in ``folder``."""
    return {p.name: read_product(p) for p in sorted(folder.glob("*.nc"))}


@pytest.mark.parametrize(
    ("preset", "status", "made"),
    [
        (
            "streamline",
            0,
            ["streamline_999_20240601_turbulence.nc", "streamline_999_20240601_wind.nc"],
        ),
        ("banakh1999", 1, []),
        ("zephir300", 1, []),
    ],
)
def test_retrieve_and_batch_agree(inputs, tmp_path, preset, status, made):
    r_status, r_notes, r_errors = run(
        ["retrieve", str(inputs), "-o", str(tmp_path / "r"), "-c", preset]
    )
    b_status, b_notes, b_errors = run(["batch", str(inputs), str(tmp_path / "b"), "-c", preset])
    assert r_status == b_status == status
    assert r_notes == b_notes
    assert r_errors == b_errors
    got_r, got_b = products(tmp_path / "r"), products(tmp_path / "b")
    assert sorted(got_r) == sorted(got_b) == made
    for name in made:
        assert sorted(got_r[name].variables) == sorted(got_b[name].variables)
        xr.testing.assert_equal(got_r[name], got_b[name])  # values, dims and coordinates
    files = sorted(inputs.glob("*.hpl"))
    if preset == "banakh1999":  # every file named with its problem, and why nothing was done
        (note,) = r_notes
        assert note.startswith("2 files of other instruments skipped (2 hpl in ")
        assert note.endswith("the configuration reads scan_netcdf only")
        (line,) = r_errors
        assert "none of the inputs is a scan_netcdf file" in line and "2 file(s)" in line
    elif preset == "zephir300":  # another instrument's configuration: each file fails
        assert len(r_errors) == len(files)
        for f in files:
            (line,) = [e for e in r_errors if str(f) in e]
            assert "pulsed lidar" in line and "ZephIR 300" in line and "-c streamline" in line
    else:
        assert r_errors == set()
        assert {f"{f}: VAD: 6 conical scan(s) -> wind (and turbulence)" for f in files} <= r_notes


def test_run_unit_reports_products_notes_and_status(inputs):
    """The API path (read_units -> run_unit) gives what the commands print."""
    from cwproc.config import load_config
    from cwproc.pipeline import EXIT_OK, read_units, run_unit

    config = load_config("zephir300")
    refused = read_units(sorted(inputs.glob("*.hpl")), config)  # another instrument's
    assert len(refused.failures) == 2 and refused.units == []
    found = read_units(sorted(inputs.glob("*.hpl")), load_config("streamline"))
    assert found.failures == [] and [u.key for u in found.units] == ["streamline_999_20240601"]
    # run_unit itself still guards the turbulence product against a cw configuration
    result = run_unit(found.units[0], config, keep_screened=True)
    assert result.ok and result.exit_status == EXIT_OK
    assert list(result.products) == ["wind"]
    assert any("turbulence not computed" in n and "cw lidar" in n for n in result.notes)
    # the screened scans are those the VAD was fitted to: one wind row per conical scan
    scans = set(result.screened["scan"].values[result.screened["scan"].values >= 0].tolist())
    assert scans == set(result.products["wind"]["scan"].values.tolist())


def test_run_unit_names_a_damaged_input_and_fails(inputs, tmp_path):
    """An input whose header reads but whose data do not: left out, named, exit status 1."""
    from cwproc.config import load_config
    from cwproc.pipeline import EXIT_FAILED, read_units, run_unit

    good = sorted(inputs.glob("*.hpl"))
    cut = tmp_path / good[1].name
    cut.write_bytes(good[1].read_bytes()[:-5000])  # the last rays cut in the middle
    config = load_config("streamline")
    found = read_units([good[0], cut], config)
    (unit,) = found.units
    for item in unit.inputs:  # as beyond the memory budget: read again when run
        item.dataset = None
    result = run_unit(unit, config)
    assert result.exit_status == EXIT_FAILED
    assert len(result.failures) == 1 and result.failures[0].startswith(f"{cut}:")
    assert "wind" in result.products  # the other file still gives its products
