"""Compile the predictor's kernels into the checkout's numba cache before the suite's workers start.

In a fresh clone every worker, and every `drs` process a test starts, compiled the same kernels until one
of them had written the cache: 76 s more for the whole suite on this machine (598.6 s against 522.5 s with
a warm cache, three workers, 2026-12-03). `make test` runs this beside the lint, which keeps one core
busy, so the compiling costs the suite no time of its own. One demo ensemble compiles 27 of the 34
kernels the suite uses; the calibration's residual kernels are left to the tests that use them.
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile


def warm() -> int:
    with tempfile.TemporaryDirectory(prefix="drs-warm-") as home:
        os.environ["XDG_CACHE_HOME"] = home  # the demo weather it writes goes with it
        from console.commands.main import main

        with open(os.devnull, "w") as quiet, contextlib.redirect_stdout(quiet):
            return main(["predict", "--demo-weather", "--lat", "46.5", "--lon", "6.6", "--alt", "28000",
                         "--time", "2026-11-22T12:00Z", "--members", "10", "--drift-minutes", "5"])  # fmt: skip


if __name__ == "__main__":
    sys.exit(warm())
