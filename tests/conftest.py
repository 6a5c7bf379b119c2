"""Fixtures shared by every test package: where the real measured data live."""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import pyproj  # noqa: F401  (before any test imports eccodes: see predictor/environment/native_libs.py)
import pytest

from tests.clock import SkipClock

os.environ.setdefault("DRS_SERVER_IDLE_S", "20")
"""The private operations servers that `drs` commands start in tests exit 20 s after their last request."""

SUITE_HOME_ENV = "DRS_TEST_SUITE_HOME"
MADE_HERE = SUITE_HOME_ENV not in os.environ
if MADE_HERE:
    os.environ[SUITE_HOME_ENV] = tempfile.mkdtemp(prefix="drs-suite-")
SUITE_HOME = Path(os.environ[SUITE_HOME_ENV])
"""This run's own home, configuration, data and cache directories, shared by its workers (they inherit the
variable from the process that made it). Before, a run read and wrote this account's: the operator's store
(``~/.local/share/drs``, and the pre-XDG places under ``~``) was opened, a configuration there could change a result, and 1.7 GB of decoded
weather had piled up in ``~/.cache/drs``, warm for every later run on this machine and cold on a fresh one."""
for _name in ("HOME", "XDG_CONFIG_HOME", "XDG_DATA_HOME", "XDG_CACHE_HOME", "XDG_STATE_HOME"):
    os.environ[_name] = str(SUITE_HOME / _name.removeprefix("XDG_").removesuffix("_HOME").lower())
    Path(os.environ[_name]).mkdir(mode=0o700, exist_ok=True)
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


LONGEST_FILES = (
    "tests/predictor/calibration/test_live_hard_worlds.py",
    "tests/console/test_release_flow.py",
    "tests/predictor/calibration/test_live_independent.py",
    "tests/predictor/prediction/test_live_real.py",
    "tests/predictor/environment/test_grib_native_faults.py",
    "tests/console/commands/test_cli_capsule.py",
    "tests/console/test_live_demo_tmux.py",
    "tests/console/test_one_rule.py",
    "tests/predictor/tawhiri/test_server_hardening.py",
    "tests/console/test_end_to_end_tmux.py",
    "tests/predictor/environment/test_demo_weather.py",
    "tests/predictor/calibration/test_ellipse_fit.py",
    "tests/predictor/calibration/test_selection_by_family.py",
    "tests/console/test_screens.py",
    "tests/console/test_live_demo.py",
    "tests/predictor/calibration/test_live_train_score.py",
    "tests/console/commands/test_cli_predict.py",
    "tests/predictor/calibration/test_vertical_contest.py",
    "tests/drs_link/server/test_fire_two_accounts.py",
    "tests/predictor/calibration/test_selection_synthetic.py",
    "tests/predictor/calibration/test_report.py",
    "tests/drs_link/server/test_stopping_server.py",
    "tests/predictor/calibration/test_preflight_held_out_report.py",
)
"""The files that took longest, longest first, which start first (``make test``'s pytest with four
workers, each test's setup + call + teardown summed per file, 2026-12-04: 68 s down to 23 s).
xdist's ``loadfile`` hands a worker whole files, by default those with the most tests first: files of
one long test (an evaluation, a demo in tmux) came last and one worker ran them alone at the end. The Makefile turns that order off (``--no-loadscope-reorder``); this one is the collection's. A
file missing here only starts later, and a stale list costs balance, never a result."""


def pytest_unconfigure(config: pytest.Config) -> None:
    if MADE_HERE:  # the run's first process made the directory, and removes it; its workers inherited it
        shutil.rmtree(SUITE_HOME, ignore_errors=True)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    rank = {path: index for index, path in enumerate(LONGEST_FILES)}

    def place(item: pytest.Item) -> int:
        path = Path(item.path)
        return (
            rank.get(path.relative_to(REPO_ROOT).as_posix(), len(rank))
            if path.is_relative_to(REPO_ROOT)
            else len(rank)
        )

    items.sort(key=place)  # stable: every other file, and the tests in each file, keep their order
