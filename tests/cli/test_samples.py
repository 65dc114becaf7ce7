"""Every shipped sample runs through its command as sample_data/README.md writes it."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from cwproc.cli import main

SAMPLE = Path(__file__).parents[2] / "sample_data"


@pytest.mark.parametrize(
    ("args", "products"),
    [
        (["retrieve", "-c", "zephir300", str(SAMPLE / "zephir")], 2),  # 10-min and 1-s
        (["retrieve", "-c", "windcube", str(SAMPLE / "windcube")], 4),  # v1, v2, v2.1, 1-min
        (["sf-type", "-c", str(SAMPLE / "sonic.toml"), str(SAMPLE / "sonic")], 5),
    ],
    ids=["zephir", "windcube", "sonic"],
)
def test_sample_commands(tmp_path, args, products):
    res = CliRunner().invoke(main, [*args, "-o", str(tmp_path / "out")])
    assert res.exit_code == 0, res.output
    assert f"{products} product(s) written, 0 failure(s)" in res.output
    assert len(list((tmp_path / "out").glob("*.nc"))) == products


def test_main_job_skips_the_other_formats_and_says_so(tmp_path):
    res = CliRunner().invoke(
        main,
        ["retrieve", str(SAMPLE), "-c", str(SAMPLE / "site.toml"), "-o", str(tmp_path / "o")],
    )
    assert res.exit_code == 0, res.output
    assert "2 input(s), 2 product(s) written, 0 failure(s)" in res.output
    assert "15 file(s) of other formats skipped (the configuration reads hpl only)" in res.output


def test_a_named_file_of_another_format_is_a_clear_failure(tmp_path):
    toa5 = next((SAMPLE / "sonic").glob("TOA5_*"))
    res = CliRunner().invoke(main, ["retrieve", "-c", "streamline", str(toa5), "-o", str(tmp_path)])
    assert res.exit_code == 1
    assert "a toa5 file, but the configuration reads only hpl" in res.output


@pytest.mark.slow
def test_zephir300_preset_reads_the_simulated_zephir_scans(tmp_path):
    sim = CliRunner().invoke(
        main,
        [
            "simulate",
            "lidar",
            "--instrument",
            "zephir",
            "-o",
            str(tmp_path / "z"),
            "--hours",
            "0.02",
        ],
    )
    assert sim.exit_code == 0, sim.output
    res = CliRunner().invoke(
        main,
        ["retrieve", "-c", "zephir300", str(tmp_path / "z" / "data"), "-o", str(tmp_path / "o")],
    )
    assert res.exit_code == 0, res.output
    assert "_wind.nc" in res.output


def test_zephir300_preset_reads_any_format():
    """The preset once forced the CSV reader on the cw scan NetCDF of simulate lidar."""
    from cwproc.config import load_config

    assert load_config("zephir300").instrument.format == "auto"
