"""Shared fixtures: where the real instrument files are (``../shared/real_data``)."""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings

# CI (CI=true) runs the property tests derandomised: a red build then always means a
# reproducible defect, never an unlucky draw; developers keep random exploration.
settings.register_profile("ci", derandomize=True, deadline=None, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")

#: the one temporary cache folder of a test session (tables, removed-share curves): set
#: at import by the controller, inherited by pytest-xdist workers (spawned later), so
#: that no test reads or writes the user's ~/.cache/cwproc
TEST_CACHE_VARIABLE = "CWPROC_TEST_CACHE"
_OWN_CACHE: str | None = None
if not os.environ.get(TEST_CACHE_VARIABLE):
    _OWN_CACHE = tempfile.mkdtemp(prefix="cwproc-test-cache-")
    os.environ[TEST_CACHE_VARIABLE] = _OWN_CACHE
os.environ["XDG_CACHE_HOME"] = os.environ[TEST_CACHE_VARIABLE]


def pytest_sessionfinish(session, exitstatus):
    """The controller (the process that made the folder) removes the session's cache."""
    if _OWN_CACHE is not None and not hasattr(session.config, "workerinput"):
        shutil.rmtree(_OWN_CACHE, ignore_errors=True)


REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("CWPROC_SHARED", REPO.parent / "shared"))
REAL_DATA = SHARED / "real_data"
REFERENCE = SHARED / "reference"


@pytest.fixture(scope="session")
def real_data() -> Path:
    """The folder of real instrument files; skips the test when it is absent."""
    if not REAL_DATA.is_dir():
        pytest.skip(f"real instrument files not available: {REAL_DATA} does not exist")
    return REAL_DATA


@pytest.fixture(scope="session")
def reference_dir() -> Path:
    """The folder of published/independent reference values; skips when absent."""
    if not REFERENCE.is_dir():
        pytest.skip(f"reference values not available: {REFERENCE} does not exist")
    return REFERENCE


#: fixtures that need the project's own files under ../shared (not shipped)
SHARED_FIXTURES = {"real_data": REAL_DATA, "reference_dir": REFERENCE}


def pytest_collection_modifyitems(config, items):
    """Without ../shared (every user's case) its tests are deselected, not skipped one by
    one: the readers are covered by the shipped samples (tests/sim/test_sample_data.py)."""
    missing = {name for name, path in SHARED_FIXTURES.items() if not path.is_dir()}
    if not missing:
        return
    keep, drop = [], []
    for item in items:
        (drop if missing & set(getattr(item, "fixturenames", ())) else keep).append(item)
    if drop:
        config.hook.pytest_deselected(items=drop)
        items[:] = keep


def _absent_note() -> str | None:
    if SHARED.is_dir():
        return None
    return (
        f"cwproc: {SHARED} is absent: tests of the project's real instrument files and "
        "reference values are deselected (the shipped samples cover every reader)"
    )


def pytest_report_header(config):
    return _absent_note()


def pytest_terminal_summary(terminalreporter):
    """The note once more at the end: ``-q`` hides the header, and with ``-n auto`` the
    workers deselect, so the summary line does not count the deselected tests."""
    note = _absent_note()
    if note:
        terminalreporter.write_line(note)


def _check(path: Path, test: str) -> dict:
    from compliance_checker.runner import CheckSuite, ComplianceChecker

    CheckSuite.load_all_available_checkers()
    out = path.with_suffix(f".{test.replace(':', '_')}.json")
    ComplianceChecker.run_checker(
        os.fspath(path),
        [test],
        verbose=0,
        criteria="normal",
        output_filename=os.fspath(out),
        output_format="json",
    )
    result = next(iter(json.loads(out.read_text()).values()))
    out.unlink()
    return result


def _compliance(path: Path) -> tuple[list[str], float]:
    """(CF-1.10 high-priority failures, ACDD-1.3 score as a fraction) of a NetCDF file."""
    cf = _check(Path(path), "cf:1.10")
    acdd = _check(Path(path), "acdd:1.3")
    high = [f"{c['name']}: {m}" for c in cf["high_priorities"] for m in c["msgs"]]
    return high, acdd["scored_points"] / acdd["possible_points"]


@pytest.fixture(scope="session")
def compliance():
    """The IOOS compliance checker as a function: path -> (CF high failures, ACDD score)."""
    pytest.importorskip("compliance_checker")
    return _compliance


def _chromatic_pixels(fig) -> list[int]:
    """Coloured (chromatic) pixels inside each data panel, legends and colour bars aside.

    Axes, text and the grey background of gaps are achromatic; data are drawn in colour.
    """
    for ax in fig.axes:
        if ax.get_legend() is not None:
            ax.get_legend().remove()
    fig.canvas.draw()
    img = np.asarray(fig.canvas.buffer_rgba())[..., :3].astype(float) / 255.0
    chroma = img.max(axis=-1) - img.min(axis=-1)
    counts = []
    height = img.shape[0]
    for ax in fig.axes:
        if hasattr(ax, "_colorbar"):
            continue
        bb = ax.get_window_extent()
        rows = slice(int(height - bb.y1) + 2, int(height - bb.y0) - 2)
        cols = slice(int(bb.x0) + 2, int(bb.x1) - 2)
        counts.append(int((chroma[rows, cols] > 0.15).sum()))
    return counts


@pytest.fixture
def data_pixels():
    """Counts of coloured pixels per data panel of a matplotlib figure (the screenshot
    check of tests/test_plots.py and tests/test_plots_stare.py)."""
    return _chromatic_pixels
