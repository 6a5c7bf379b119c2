"""Where numba keeps the predictor's compiled code: somewhere writable, however drs is installed.

numba refuses to import a function compiled with ``cache=True`` when it finds no writable cache
directory (``RuntimeError: cannot cache function …: no locator available``): it tries beside the
sources (``__pycache__``) and the account's own cache (``~/.cache/numba``). Under the operations
server's hardened unit (a read-only installation, ``ProtectHome``, an account without a home) neither
exists, so the server could not even load the predictor that go/no-go's "release now" prediction
flies (reproduced by importing ``predictor.descent.integrate`` as such an account). Then a directory
of this account's own under the temporary directory takes the cache. A ``NUMBA_CACHE_DIR`` given by
whoever runs drs (the unit sets one that survives restarts) is always kept.
"""

from __future__ import annotations

import os
import stat
import tempfile
from pathlib import Path

from numba.core import config
from numba.core.caching import InTreeCacheLocator, UserWideCacheLocator


def ensure_cache_dir(source: str) -> None:
    """Give numba a cache directory for the functions of the module at ``source`` if it has none.

    Called at the top of each module that compiles with ``cache=True``, before its decorators run.
    """
    if config.CACHE_DIR:  # type: ignore[attr-defined]  # numba's config sets its names at run time
        return
    for locator in (InTreeCacheLocator, UserWideCacheLocator):
        if locator.from_function(ensure_cache_dir, source) is not None:
            return
    config.CACHE_DIR = str(private_cache_dir(Path(tempfile.gettempdir())))  # type: ignore[attr-defined]


def private_cache_dir(parent: Path) -> Path:
    """``parent/drs-numba-<uid>``, made 0700; or, if that name is taken by anything but this account's
    own private directory, a fresh one. numba's cache index is a pickle that it loads, so a directory
    another account can write into would let that account run code as this one."""
    mine = parent / f"drs-numba-{os.getuid()}"
    try:
        mine.mkdir(mode=0o700, exist_ok=True)
        found = mine.lstat()
    except OSError:
        return Path(tempfile.mkdtemp(prefix="drs-numba-", dir=parent))
    private = stat.S_ISDIR(found.st_mode) and found.st_uid == os.getuid() and not found.st_mode & 0o077
    return mine if private else Path(tempfile.mkdtemp(prefix="drs-numba-", dir=parent))
