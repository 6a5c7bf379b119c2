"""What every `drs` command shares, through the real entry point: version, log level, exit statuses, typos."""

from __future__ import annotations

import importlib.metadata
import io
import logging
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from console.commands.logs import configure_logging
from console.commands.main import main

REPO = Path(__file__).resolve().parents[3]


def drs(*argv: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "console.commands.main", *argv], cwd=REPO, capture_output=True, text=True, timeout=120,
        env={**os.environ, **(env or {})},
    )  # fmt: skip


def test_version_names_the_installed_distribution() -> None:
    done = drs("--version")
    assert (done.returncode, done.stdout) == (0, f"drs {importlib.metadata.version('drs-console')}\n")


def test_a_mistyped_option_is_named_with_the_close_real_one() -> None:
    """It once said "argument action: invalid choice: '67.89' (choose from 'bench')"."""
    done = drs("predict", "--lattitude", "67.89")
    assert done.returncode == 2 and "invalid choice" not in done.stderr
    assert (
        done.stderr.splitlines()[-1]
        == "drs predict: error: unrecognized option --lattitude (did you mean --lat?)"
    )


@pytest.mark.parametrize(
    ("argv", "last_line"),
    [
        (
            ["mo", "health", "DRS1", "--jsn"],
            "drs mo health: error: unrecognized option --jsn (did you mean --json?)",
        ),
        (
            ["mt", "status", "DRS1", "--json=yes", "--xyzzy"],
            "drs mt status: error: unrecognized option --xyzzy",
        ),
        (
            ["--confg", "x.toml", "mo", "health"],
            "drs: error: unrecognized option --confg (did you mean --config?)",
        ),
        (["predict", "--lat", "-12.5", "--bogus=4"], "drs predict: error: unrecognized option --bogus"),
        (
            ["mo", "serve", "-vv"],
            "drs mo serve: error: unrecognized option -vv here: it is an option of drs itself, "
            "given before the command (drs -vv …)",
        ),
    ],
)
def test_an_unknown_option_is_named_wherever_it_is(
    argv: list[str], last_line: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """A negative number is a value, and ``--opt=value`` is judged by its option."""
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 2 and capsys.readouterr().err.splitlines()[-1] == last_line


def test_a_usage_error_exits_2_and_an_operational_failure_1(tmp_path: Path) -> None:
    config = tmp_path / "drs.toml"
    config.write_text(f'[data]\ndir = "{tmp_path / "data"}"\n')
    refused = drs("--config", str(config), "mo", "health", "DRS1")
    assert refused.returncode == 1
    assert refused.stderr == f"drs: error: no capsule named 'DRS1' in {config} (known: none configured)\n"
    meaningless = drs("--config", str(config), "mo", "export", "--out", str(tmp_path / "t.csv"))
    assert meaningless.returncode == 2
    assert (
        meaningless.stderr == "drs: error: give either a capsule NAME or --imei IMEI, not both or neither\n"
    )
    assert drs("--config", str(config), "mo", "health").returncode == 2  # argparse: NAME is missing


def test_log_level_and_verbose_choose_what_reaches_stderr(tmp_path: Path) -> None:
    """The warning here is real: a config found only in its pre-XDG place is used and said so."""
    home = tmp_path / "home"
    (home / ".config" / "drs").mkdir(parents=True)
    (home / ".config" / "drs" / "drs.toml").write_text(
        f'[data]\ndir = "{tmp_path / "data"}"\n[[capsule]]\nname = "DRS1"\nhost = "h"\nimei = "300234010753370"\n'
    )
    env = {"HOME": str(home), "XDG_CONFIG_HOME": str(tmp_path / "xdg"), "DRS_CONFIG": ""}
    shown = drs("mo", "health", "DRS1", env=env)
    assert shown.returncode == 0 and shown.stdout.startswith("DRS1: 0 reports")
    [warning] = shown.stderr.splitlines()
    assert (
        " WARNING drs_link.config: using " in warning
        and str(tmp_path / "xdg" / "drs" / "drs.toml") in warning
    )
    assert drs("--log-level", "error", "mo", "health", "DRS1", env=env).stderr == ""
    debug = drs("-vv", "mo", "health", "DRS1", env=env).stderr
    assert " WARNING drs_link.config: " in debug
    assert drs("--log-level", "loud", "mo", "health", "DRS1", env=env).returncode == 2


def test_records_are_one_line_with_fields_and_libraries_speak_only_at_debug(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """paramiko logs ERROR for a reset the link reports itself: an operator must see that failure once."""
    root = logging.getLogger()
    before, level = list(root.handlers), root.level
    try:
        configure_logging(logging.WARNING)
        logging.getLogger("paramiko.transport").error("Socket exception: Connection reset by peer (104)")
        logging.getLogger("drs_link.test").warning(
            "refused", extra={"client": "192.0.2.7", "reason": 'a "b"\nc'}
        )
        [line] = capsys.readouterr().err.splitlines()
        assert re.fullmatch(
            r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{3}Z WARNING drs_link\.test: refused .*", line
        )
        assert line.endswith(' client=192.0.2.7 reason="a \\"b\\"\\nc"')
        configure_logging(logging.DEBUG)
        logging.getLogger("paramiko.transport").error("Socket exception")
        assert " ERROR paramiko.transport: Socket exception" in capsys.readouterr().err
        later = io.StringIO()  # stderr replaced after the run began (a test's capture closed, a redirect)
        monkeypatch.setattr(sys, "stderr", later)
        logging.getLogger("drs_link.test").warning("still heard")
        assert later.getvalue().endswith(" WARNING drs_link.test: still heard\n")
    finally:
        root.handlers[:] = before
        root.setLevel(level)
