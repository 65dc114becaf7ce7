"""cwproc's own products among the inputs are skipped, and said to be, by every command
that reads a folder: a second run over the same folder reads the same inputs."""

from __future__ import annotations

import shutil
from pathlib import Path

from click.testing import CliRunner

from cwproc.batch import PRODUCT_FORMAT, classify_file
from cwproc.cli import main
from cwproc.config import Config
from cwproc.io import is_cwproc_product

SAMPLE = Path(__file__).parents[2] / "sample_data" / "streamline"


def test_retrieve_twice_into_a_folder_inside_the_input(tmp_path):
    data = tmp_path / "mydata"
    data.mkdir()
    shutil.copy(next(SAMPLE.glob("*.hpl")), data)
    args = ["retrieve", str(data), "-o", str(data / "products")]
    first = CliRunner().invoke(main, args)
    assert first.exit_code == 0, first.output
    products = sorted((data / "products").glob("*.nc"))
    assert len(products) == 2 and all(is_cwproc_product(p) for p in products)
    second = CliRunner().invoke(main, args)
    assert second.exit_code == 0, second.output
    assert "1 input(s), 2 product(s) written, 0 failure(s)" in second.output
    assert "2 cwproc product(s) skipped (not instrument files)" in second.output


def test_batch_classifies_a_product_as_skipped(tmp_path):
    out = tmp_path / "out"
    res = CliRunner().invoke(main, ["retrieve", str(SAMPLE), "-o", str(out)])
    assert res.exit_code == 0, res.output
    product = next(out.glob("*_wind.nc"))
    info = classify_file(str(product), Config().to_toml())
    assert info.status == "unrecognised" and info.format == PRODUCT_FORMAT
    assert "a cwproc product, not an instrument file" in info.error


def test_scan_files_are_not_products():
    assert not is_cwproc_product(next(SAMPLE.glob("*.hpl")))
