"""The compiled predictor loads where numba finds no writable cache beside the sources or in a home
(the operations server's hardened unit), in a directory only this account can write."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from numba.core import config

from predictor.numba_cache import ensure_cache_dir, private_cache_dir


@pytest.fixture
def nowhere_writable(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A module whose ``__pycache__`` cannot be made (a file holds the name, so even root fails) and an
    account cache under a file; numba's own ``NUMBA_CACHE_DIR`` unset."""
    source = tmp_path / "src" / "kernels.py"
    source.parent.mkdir()
    source.write_text("")
    (source.parent / "__pycache__").write_text("not a directory")
    (tmp_path / "home").write_text("not a directory")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "home" / "cache"))
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.setenv("TMPDIR", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    monkeypatch.setattr(config, "CACHE_DIR", "")
    return source


def test_with_no_writable_cache_a_private_directory_under_the_temporary_one_takes_it(
    nowhere_writable: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", None)  # gettempdir() reads TMPDIR again
    ensure_cache_dir(str(nowhere_writable))
    cache = Path(config.CACHE_DIR)
    assert cache == tmp_path / "tmp" / f"drs-numba-{os.getuid()}"
    assert cache.is_dir() and cache.stat().st_mode & 0o777 == 0o700


def test_a_cache_directory_given_by_the_caller_is_kept(
    nowhere_writable: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(config, "CACHE_DIR", str(tmp_path / "given"))
    ensure_cache_dir(str(nowhere_writable))
    assert config.CACHE_DIR == str(tmp_path / "given")


def test_a_writable_pycache_beside_the_sources_is_left_to_numba(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    source = tmp_path / "kernels.py"
    source.write_text("")
    monkeypatch.setattr(config, "CACHE_DIR", "")
    ensure_cache_dir(str(source))
    assert config.CACHE_DIR == ""


@pytest.mark.parametrize("planted", ["open to the group", "another account's", "a symlink"])
def test_a_name_another_account_could_have_planted_is_never_used(tmp_path: Path, planted: str) -> None:
    """numba loads its cache index with pickle: a directory another account can write is their code."""
    name = tmp_path / f"drs-numba-{os.getuid()}"
    if planted == "a symlink":
        (tmp_path / "elsewhere").mkdir(mode=0o700)
        name.symlink_to(tmp_path / "elsewhere")
    else:
        name.mkdir(mode=0o700)
        if planted == "open to the group":
            name.chmod(0o770)
        elif os.getuid() == 0:
            os.chown(name, 65534, 65534)
        else:
            pytest.skip("making a directory another account's needs root")
    cache = private_cache_dir(tmp_path)
    assert cache != name and cache.parent == tmp_path and cache.stat().st_mode & 0o777 == 0o700


def test_the_compiled_predictor_imports_with_only_the_fallback_directory(tmp_path: Path) -> None:
    """A fresh process that may write neither beside the sources nor in a home (both names taken by
    files) still imports the compiled predictor; the cache lands in the fallback."""
    script = (
        "import numba.core.caching as c, predictor.numba_cache as n\n"
        "c.InTreeCacheLocator.from_function = classmethod(lambda cls, f, p: None)\n"
        "c.UserWideCacheLocator.from_function = classmethod(lambda cls, f, p: None)\n"
        "import predictor.descent.integrate as i\n"
        "from numba.core import config\n"
        "print(config.CACHE_DIR)\n"
    )
    env = {**os.environ, "TMPDIR": str(tmp_path)}
    env.pop("NUMBA_CACHE_DIR", None)
    done = subprocess.run(
        [sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == str(tmp_path / f"drs-numba-{os.getuid()}")
