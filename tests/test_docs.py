"""The reference pages in docs/ are exactly what the code generates."""

from __future__ import annotations

from pathlib import Path

import pytest

from cwproc.reference_docs import PAGES

DOCS = Path(__file__).resolve().parents[1] / "docs"


@pytest.mark.parametrize("name", sorted(PAGES))
def test_generated_page_is_current(name):
    committed = (DOCS / name).read_text(encoding="utf-8")
    assert committed == PAGES[name](), (
        f"docs/{name} is out of date: run `python -m cwproc.reference_docs docs/`"
    )


def test_config_reference_lists_every_option():
    import dataclasses

    from cwproc.config import Config

    text = PAGES["config.md"]()
    for section in dataclasses.fields(Config):
        value = getattr(Config(), section.name)
        if dataclasses.is_dataclass(value):
            for f in dataclasses.fields(value):
                assert f"`{f.name}`" in text, f"{section.name}.{f.name} undocumented"


def test_every_preset_is_described():
    from cwproc.config import preset_names
    from cwproc.reference_docs import preset_description

    for name in preset_names():
        assert len(preset_description(name)) > 20, f"preset {name} has no leading comment"
