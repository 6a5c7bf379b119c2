"""Every damaged GRIB file is refused in one line naming it, under a memory cap and a time bound (issue #24
item 2: one flipped byte made Ni 2,386,165,793 and the reader grew to 23 GB until the OOM killer struck).

The mutants are committed in ``grib_mutants/`` (how they were chosen: ``grib_mutation.py``). They are read by
``load_weather``, the path `drs predict` takes, in a child process whose address space is capped at 1.5 GiB
(``RLIMIT_AS``): an allocation from a damaged header then fails there as a MemoryError instead of taking the
machine, and the test sees it as the crash it is.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from tests.predictor.environment.grib_mutation import CAP_BYTES, CHILD, FOLDER

REPO = Path(__file__).resolve().parents[3]
HEADER_DAMAGE = [
    "ni-2386165793", "ni-2386165793-every-message", "nj-4000000000-every-message", "ni-100000-nj-100000",
    "ni-0", "ni-7-every-message", "data-points-huge", "values-count-huge", "year-0", "year-65535", "month-13",
    "day-0", "hour-99", "minute-250", "forecast-time-huge", "latitude-first-900", "cut-mid-message",
]  # fmt: skip
"""Mutants no reader may accept: each names a header value no weather file has, or a cut."""


def test_every_grib_mutant_is_read_or_refused_in_one_line_naming_it_under_a_memory_cap(
    tmp_path: Path,
) -> None:
    child = subprocess.run(
        [sys.executable, "-c", CHILD, str(CAP_BYTES), str(FOLDER)],
        cwd=REPO, capture_output=True, text=True, timeout=180,
        env={"PYTHONPATH": str(REPO), "HOME": str(tmp_path)},
    )  # fmt: skip
    assert child.returncode == 0, child.stderr[-2000:]
    answers = {a["file"].removesuffix(".grib2"): a for a in map(json.loads, child.stdout.splitlines())}
    assert len(answers) == len(list(FOLDER.glob("*.grib2"))) >= 30
    crashed = {name: a["message"] for name, a in answers.items() if a["outcome"] == "crashed"}
    assert crashed == {}, "no traceback and no out-of-memory"
    assert answers["base"]["outcome"] == "read", answers["base"]
    for name, answer in answers.items():
        if answer["outcome"] == "refused":
            assert "\n" not in answer["message"] and f"{name}.grib2" in answer["message"], answer
    accepted = sorted(name for name in HEADER_DAMAGE if answers[name]["outcome"] != "refused")
    assert accepted == []
