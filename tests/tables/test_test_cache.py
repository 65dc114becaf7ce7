"""The tests use a temporary cache of their session, never the user's ~/.cache/cwproc."""

from __future__ import annotations

import os
from pathlib import Path

import platformdirs

from cwproc.tables import store as disk_cache


def test_the_cache_of_the_tests_is_a_temporary_folder_not_the_users():
    used = Path(disk_cache.cache_path(None, "atable", "x")).parent.resolve()
    session = Path(os.environ["CWPROC_TEST_CACHE"]).resolve()
    assert used == session / "cwproc"
    assert Path(platformdirs.user_cache_dir("cwproc")).resolve() == used
    home_cache = (Path.home() / ".cache").resolve()
    assert home_cache not in used.parents
    assert used != (home_cache / "cwproc")
