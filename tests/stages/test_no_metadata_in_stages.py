"""Metadata has one home (issues 16, 33): no stage sets a name, unit, flag or citation.

The CF attributes are declared once, in :mod:`cwproc.metadata` (the products in
:mod:`cwproc.metadata.products`, the canonical inputs in
:mod:`cwproc.metadata.canonical`); the decorator :func:`cwproc.metadata.described`
attaches them to what a stage returns, and the writer again to what it writes. The
stage code itself records only what it did (``method``, its parameters). The source of every
stage module is scanned: a declared attribute name used as a string key of a dict
literal (``{"units": ...}``, the attrs of ``(dims, values, attrs)``), as a keyword of
``.attrs.update(...)``/``dict(...)``, or as a subscript assigned into ``.attrs``.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from cwproc.metadata import DECLARED_ATTRS

ROOT = Path(__file__).resolve().parents[2] / "cwproc"
#: the retrieval stages, and the scan bookkeeping they share with the readers
SCANNED = [*sorted((ROOT / "stages").rglob("*.py")), ROOT / "io" / "scan_join.py"]


def _key(node: ast.AST | None) -> str | None:
    return node.value if isinstance(node, ast.Constant) and isinstance(node.value, str) else None


def _is_attrs(node: ast.AST) -> bool:
    """``<anything>.attrs``."""
    return isinstance(node, ast.Attribute) and node.attr == "attrs"


def declared_keys_set(source: str) -> list[tuple[int, str]]:
    """``(line, attribute)`` of every declared attribute the code in ``source`` sets."""
    found: list[tuple[int, str]] = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Dict):
            found += [(node.lineno, k) for k in map(_key, node.keys) if k in DECLARED_ATTRS]
        elif isinstance(node, ast.Call):
            func = node.func
            is_update = (
                isinstance(func, ast.Attribute) and func.attr == "update" and _is_attrs(func.value)
            )
            is_dict = isinstance(func, ast.Name) and func.id == "dict"
            if is_update or is_dict:
                found += [
                    (node.lineno, str(kw.arg)) for kw in node.keywords if kw.arg in DECLARED_ATTRS
                ]
        elif isinstance(node, ast.Assign | ast.AugAssign):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for target in targets:
                if isinstance(target, ast.Subscript) and _is_attrs(target.value):
                    key = _key(target.slice)
                    if key in DECLARED_ATTRS:
                        found.append((node.lineno, key))
    return found


@pytest.mark.parametrize(
    "code",
    [
        'out["u"].attrs["units"] = "m s-1"',
        'out["u"].attrs.update(references="a paper")',
        'out["u"].attrs.update({"long_name": "eastward wind"})',
        'xr.Dataset({"f": (dims, flag, {"flag_meanings": "a b"})})',
        'attrs = dict(method="m", flag_masks=[1, 2])',
        'ds.attrs["comment"] = "c"',
    ],
)
def test_the_scan_finds_each_way_of_setting_an_attribute(code):
    assert [key for _, key in declared_keys_set(code)], code


def test_the_scan_lets_a_stage_record_its_method_and_parameters():
    code = (
        'out["u"].attrs.update(method="least squares", min_rays=6)\n'
        'out["qc_flag_radial"] = (dims, flag, {"method": "m", "snr_min": 0.008})\n'
        'out.attrs["vad_references"] = REFERENCES\n'
    )
    assert declared_keys_set(code) == []


def test_no_stage_sets_a_declared_attribute():
    assert len(SCANNED) > 10  # the stages package was found
    offences = [
        f"{path.relative_to(ROOT.parent)}:{line}: {key}"
        for path in SCANNED
        for line, key in declared_keys_set(path.read_text(encoding="utf-8"))
    ]
    assert offences == [], "declare these in cwproc/metadata/ instead:\n" + "\n".join(offences)
