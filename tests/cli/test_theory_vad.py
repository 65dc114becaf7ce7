"""``cwproc theory vad-errors`` prints the seed 002 error tables (REFERENCE_VALUES.md 2.2)."""

from __future__ import annotations

import re

import pytest
from click.testing import CliRunner

from cwproc.cli import main


def run(*args: str):
    return CliRunner().invoke(main, ["theory", "vad-errors", *args])


def rows(output: str, title_word: str) -> dict[str, list[float]]:
    """The component rows of the table whose title contains ``title_word``."""
    block = output.split(title_word, 1)[1].split("\n\n", 1)[0]
    found = {}
    for line in block.splitlines():
        m = re.match(r"^(V[xyz])\s+(.*)$", line)
        if m:
            found[m.group(1)] = [float(x) for x in m.group(2).split()]
    return found


def test_missing_sector_table_matches_reference() -> None:
    # REFERENCE_VALUES.md 2.2, N = 72, s = 60 deg, phi = 35.3 deg, per unit bound
    result = run("--phi", "35.3", "--n-azimuths", "72", "--sector", "60", "--bound", "1")
    assert result.exit_code == 0, result.output
    assert "61 azimuths kept" in result.output
    table = rows(result.output, "maximum errors")
    decoupled, least_squares, asymptote, linear = zip(*table.values(), strict=True)
    assert decoupled == pytest.approx((1.67269, 1.50514, 1.73053), abs=1e-5)
    assert least_squares == pytest.approx((1.73873, 1.50514, 1.73053), abs=1e-5)
    assert asymptote == pytest.approx((1.68233, 1.49879, 1.73053), abs=1e-5)
    assert linear[0] == pytest.approx(1.67168, abs=1e-5)
    assert "RMS errors" not in result.output


def test_sigma_gives_rms_table() -> None:
    # REFERENCE_VALUES.md 2.1: N = 24, phi = 60: rms dVx 0.57735, rms dVz 0.23570 per sigma
    result = run("--phi", "60", "--n-azimuths", "24", "--sigma", "2")
    assert result.exit_code == 0, result.output
    table = rows(result.output, "RMS errors")
    assert table["Vx"][1] == pytest.approx(2 * 0.57735, abs=2e-5)
    assert table["Vz"][1] == pytest.approx(2 * 0.23570, abs=2e-5)
    assert "maximum errors" not in result.output


def test_gradient_and_tilt_tables() -> None:
    # REFERENCE_VALUES.md 2.3 (N = 8, phi = 60) and 2.4 (phi = 60, gamma = 1, N = 72)
    result = run("--phi", "60", "--n-azimuths", "8", "--du-dx", "0.001", "--dv-dx", "0.001")
    assert result.exit_code == 0, result.output
    grad = rows(result.output, "linear horizontal gradient")
    assert [r[0] for r in grad.values()] == pytest.approx([0.0, 0.0, 0.144338], abs=1e-5)
    assert [r[1] for r in grad.values()] == pytest.approx([0.603553, 0.353553, 0.216506], abs=1e-5)
    result = run("--phi", "60", "--n-azimuths", "72", "--tilt", "1", "--wind-x", "10",
                 "--wind-z", "0.5", "--shear-dz", "0.02")  # fmt: skip
    tilt = rows(result.output, "tilted")
    assert tilt["Vx"] == pytest.approx([-0.008727, -0.018162], abs=1e-5)
    assert tilt["Vz"] == pytest.approx([0.124150, 0.124029], abs=1e-5)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("--sigma", "1", "--bound", "1"), "not both"),
        (("--phi", "95"), "--phi"),
        (("--n-azimuths", "2"), "at least 3"),
        (("--n-azimuths", "3", "--sector", "180"), "too few"),
        (("--sigma", "-1"), "--sigma must be > 0"),
    ],
)
def test_bad_options_are_usage_errors(args: tuple[str, ...], message: str) -> None:
    result = run(*args)
    assert result.exit_code == 2
    assert message in result.output
