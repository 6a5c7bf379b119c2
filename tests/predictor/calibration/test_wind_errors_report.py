"""The committed wind-error measurement (issue #30 item 4) is what its script writes on the real flights:
deterministic (a seeded bootstrap on committed data), so it cannot drift from the code unnoticed."""

from __future__ import annotations

from pathlib import Path

from tests.approx import assert_text_close
from tests.conftest import REPO_ROOT
from tests.docs_scripts import load_docs_script

SCRIPT = REPO_ROOT / "docs" / "planning" / "wind_errors.py"


def test_the_committed_wind_error_report_is_what_the_script_writes(shared_data: Path) -> None:
    superbit = sorted((shared_data / "tracks" / "pyballoon_superbit").glob("*-*.csv"))
    eoss = sorted((REPO_ROOT / "tests" / "data" / "eoss").glob("*_descent.csv"))
    text = load_docs_script(SCRIPT).report(superbit, eoss)
    assert_text_close(text, (REPO_ROOT / "docs" / "planning" / "wind-errors.md").read_text(encoding="utf-8"))
    # What the ellipse and the shipped wind rest on: on SuperBIT the error's size grows with the
    # distance from the ascent, and below 12.5 km the error carries to the air 1–3 km below.
    assert "distance 0.54 (0.39–0.68)" in text
    assert "| 0.5–1.5 | 0.59 (0.43–0.67) | 0.43 (0.06–0.73) | 0.60 (0.43–0.68) |" in text
