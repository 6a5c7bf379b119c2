"""The committed measurement of issue #30's pre-flight floor held out whole (SuperBIT 2018 → 2019 and
2019 → 2018, EOSS leave-one-out nested) is what its script writes on the real flights: deterministic
(committed data, the calibration's fixed seed, a seeded bootstrap), so the floors it reports met and
missed cannot drift from the code unnoticed."""

from __future__ import annotations

from pathlib import Path

from tests.approx import assert_text_close
from tests.conftest import REPO_ROOT
from tests.docs_scripts import load_docs_script

SCRIPT = REPO_ROOT / "docs" / "calibration" / "preflight_held_out.py"


def test_pre_flight_is_never_worse_than_the_plain_law_held_out_whole(shared_data: Path) -> None:
    superbit = sorted((shared_data / "tracks" / "pyballoon_superbit").glob("*-*.csv"))
    eoss = sorted((REPO_ROOT / "tests" / "data" / "eoss").glob("*_descent.csv"))
    unseen = sorted((REPO_ROOT / "tests" / "data" / "eoss" / "unseen").glob("*_descent.csv"))
    text = load_docs_script(SCRIPT).report(superbit, eoss, unseen)
    assert_text_close(
        text, (REPO_ROOT / "docs" / "calibration" / "preflight-held-out.md").read_text(encoding="utf-8")
    )
    # The pre-flight gate keeps every shape term live-only and then finds the training flights' median λ
    # no better than λ = 1 beyond its interval on every training set: the plain law flies pre-flight, so
    # every split meets the floor at 1.00× (2019's median λ made 2018's descent time 1.35× before).
    splits = ("SuperBIT 2018 → 2019", "SuperBIT 2019 → 2018", "EOSS leave-one-out", "EOSS → unseen EOSS")
    for split in (*splits, "SuperBIT 2018–2019 → unseen EOSS"):
        for what in ("descent time", "landing"):
            assert f"* {split}, {what}: 1.00× the plain law, met" in text
    assert "MISSED" not in text
