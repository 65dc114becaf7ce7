"""Shared fixtures: where the real instrument files are (``../shared/real_data``)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

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
