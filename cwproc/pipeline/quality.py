"""Quality reports beside the products (``[output] qc_report``, ``cwproc retrieve --qc-report``).

For every product written, ``<product>.qc.json``: the report of
:func:`cwproc.products.quality.quality_report` with the CF-1.10 and ACDD-1.3 results of
the IOOS compliance checker when it is installed (``pip install compliance-checker``;
otherwise the two tests say they were not run and why), and the inputs of the unit that
were refused.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import tempfile
import warnings
from collections.abc import Sequence
from pathlib import Path

from cwproc.io.netcdf import read_product, write_bytes_atomic
from cwproc.pipeline.run import MAIN_VARIABLES
from cwproc.products.quality import quality_report

#: main variable of the products not in MAIN_VARIABLES (their coverage)
_MAIN = {
    **{name: var for name, (var, _) in MAIN_VARIABLES.items()},
    "doppler-lidar": "beta_raw",
    "doppler-lidar-wind": "uwind_raw",
}


def report_path(product: str | os.PathLike) -> Path:
    """``<product without .nc>.qc.json``."""
    p = Path(product)
    return p.with_name(p.name.removesuffix(".nc") + ".qc.json")


def compliance_summary(path: str | os.PathLike) -> dict[str, object]:
    """CF-1.10 failures (high and medium priority) and the ACDD-1.3 score of a file,
    or ``{"skipped": reason}`` when the IOOS compliance checker cannot run."""
    try:
        from compliance_checker.runner import CheckSuite, ComplianceChecker
    except ImportError:
        return {"skipped": "compliance-checker is not installed (pip install compliance-checker)"}
    quiet = io.StringIO()  # the checker prints which standard-name table it uses
    with (
        contextlib.redirect_stdout(quiet),
        contextlib.redirect_stderr(quiet),
        warnings.catch_warnings(),
    ):
        warnings.simplefilter("ignore")  # its own deprecations, not the user's business
        CheckSuite.load_all_available_checkers()
    results = {}
    for test in ("cf:1.10", "acdd:1.3"):
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "report.json"
            try:  # the checker prints which standard-name table it uses: not ours to show
                with (
                    contextlib.redirect_stdout(quiet),
                    contextlib.redirect_stderr(quiet),
                    warnings.catch_warnings(),
                ):
                    warnings.simplefilter("ignore")
                    ComplianceChecker.run_checker(
                        os.fspath(path),
                        [test],
                        verbose=0,
                        criteria="normal",
                        output_filename=os.fspath(out),
                        output_format="json",
                    )
                results[test] = next(iter(json.loads(out.read_text()).values()))
            except Exception as exc:  # the checker's own failure: reported, not raised
                return {"skipped": f"compliance checker failed: {type(exc).__name__}: {exc}"}
    cf, acdd = results["cf:1.10"], results["acdd:1.3"]

    def messages(key: str) -> list[str]:
        return [f"{c['name']}: {m}" for c in cf.get(key, []) for m in c.get("msgs", [])]

    return {
        "cf_high": messages("high_priorities"),
        "cf_medium": messages("medium_priorities"),
        "acdd_score": acdd["scored_points"] / max(acdd["possible_points"], 1),
    }


def write_quality_reports(
    written: Sequence[Path], refused: Sequence[str], notes: Sequence[str]
) -> list[Path]:
    """Write ``<product>.qc.json`` beside every product in ``written``; returns them.

    ``refused``: failure lines of the unit's inputs; ``notes``: the unit's notes, of
    which those naming an input left out (``not used``) go into the report.
    """
    left_out = [n for n in notes if "not used" in n or "not computed" in n]
    out = []
    for path in written:
        name = Path(path).name.removesuffix(".nc")
        product = next((p for p in sorted(_MAIN, key=len, reverse=True) if name.endswith(p)), "")
        ds = read_product(path)
        try:
            report = quality_report(
                ds,
                file=Path(path).name,
                product=product,
                main_variable=_MAIN.get(product),
                compliance=compliance_summary(path),
                refused=refused,
                notes=left_out,
            )
        finally:
            ds.close()
        text = json.dumps(report, indent=2, sort_keys=False) + "\n"
        out.append(write_bytes_atomic(report_path(path), text.encode("utf-8")))
    return out
