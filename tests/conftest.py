"""Fixtures shared by every test package: where the real measured data live."""

from __future__ import annotations

import os
from pathlib import Path

import pyproj  # noqa: F401  (before any test imports eccodes: see predictor/environment/native_libs.py)
import pytest

from tests.clock import SkipClock

os.environ.setdefault("DRS_SERVER_IDLE_S", "20")
"""The private operations servers that `drs` commands start in tests exit 20 s after their last request."""
REPO_ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO_ROOT.parent / "shared" / "data"


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """../shared/data beside the checkout (tests only; the product never reads it)."""
    if not SHARED_DATA.is_dir():
        pytest.fail(f"the real test data are missing: expected {SHARED_DATA}")
    return SHARED_DATA


@pytest.fixture
def skip_clock(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> SkipClock:
    """This test's wall clock, and that of the processes it starts from now on, skipped on demand."""
    return SkipClock(tmp_path / "skip-clock", monkeypatch)
