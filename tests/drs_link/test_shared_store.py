"""Two OS accounts share one store (`drs setup shared-store`): one account's request is approved by the other.

Real parts: two accounts and a group made with useradd/groupadd for the test, processes running with
those accounts' uids (the kernel's, as the two-person rule counts them), the real file modes, SQLite's
WAL files and `drs approve`. The processes are forks of this one that drop root before running the
command: this machine's Python lives under /root, which other accounts cannot enter, so a fresh
interpreter could not start as them; what the test checks (the kernel's permission checks on the
store, the uid as the login) is the same in a fork.
"""

from __future__ import annotations

import os
import shutil
import stat
import subprocess
import tempfile
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

import console.commands.approve  # noqa: F401 - imported before the forks drop root (see the docstring)
import console.commands.setup  # noqa: F401
from console.commands.main import main
from drs_link.config import load_config
from drs_link.errors import StoreError
from drs_link.ops.approval import ApprovalBook, Login, current_login
from drs_link.store import Store, share_directory
from tests.drs_link.server.team import as_account

pytestmark = pytest.mark.skipif(
    os.geteuid() != 0 or shutil.which("useradd") is None,
    reason="creates two OS accounts with useradd/groupadd, which needs root (CI runs as root)",
)


@pytest.fixture
def accounts() -> Iterator[tuple[str, str, str]]:
    """Two new accounts (alice, bob) in a new group of operators; removed afterwards."""
    tag = f"{os.getpid() % 100000}{uuid.uuid4().hex[:4]}"  # unique per worker and run, within 32 chars
    group, alice, bob = f"drsops{tag}", f"drsalice{tag}", f"drsbob{tag}"
    subprocess.run(["groupadd", group], check=True)
    try:
        for user in (alice, bob):
            subprocess.run(["useradd", "-M", "-N", "-G", group, "-s", "/usr/sbin/nologin", user], check=True)
        yield alice, bob, group
    finally:
        for user in (alice, bob):
            subprocess.run(["userdel", user], check=False, capture_output=True)
        subprocess.run(["groupdel", group], check=False, capture_output=True)


@pytest.fixture
def place() -> Iterator[Path]:
    """A directory every account can enter and make its own in, like /tmp (pytest's tmp_path is 0700)."""
    path = Path(tempfile.mkdtemp(prefix="drs-shared-"))
    path.chmod(0o1777)
    yield path
    shutil.rmtree(path, ignore_errors=True)


def config_for(place: Path, operator: str, store: Path) -> Path:
    path = place / f"{operator}.toml"
    path.write_text(f'[operator]\nname = "{operator}"\n[data]\ndir = "{store}"\n')
    path.chmod(0o644)
    return path


def test_one_accounts_request_is_approved_by_the_other_through_a_shared_store(
    accounts: tuple[str, str, str], place: Path
) -> None:
    alice, bob, group = accounts
    store_dir = place / "data"
    alice_config = config_for(place, alice, store_dir)
    # Once as root, so every module `drs approve` needs is imported before a fork drops root; then the
    # store goes again, for alice to make it as she would in the field.
    assert main(["--config", str(alice_config), "approve"]) == 0
    shutil.rmtree(store_dir)

    def request() -> int:
        load_config(alice_config)
        book = ApprovalBook(Store.open(store_dir / "drs.sqlite"))
        made = book.request("DRS1", "parachute", "[PARACHUTE=01:19]", alice, current_login())
        print(f"request #{made.id} by {made.requester}")
        return 0

    code, out = as_account(alice, request)
    assert code == 0 and f"request #1 by {alice}" in out, out

    def approve() -> int:  # the ops layer on the shared store (drs approve itself now asks the server)
        decided = ApprovalBook(Store.open(store_dir / "drs.sqlite")).decide(1, bob, current_login(), True)
        print(f"approved by {decided.decided_by} ({decided.decider})")
        return 0

    code, out = as_account(bob, approve)
    assert code != 0, out
    assert f"it belongs to {alice}" in out and "drs setup shared-store" in out, (
        "the refusal says how to share"
    )

    code, out = as_account(alice, lambda: main(["setup", "shared-store", str(store_dir), "--group", group]))
    assert code == 0, out
    assert (
        f"{store_dir}: group {group}, mode 2770" in out
        and f"{store_dir / 'drs.sqlite'}: group {group}" in out
    )
    assert stat.S_IMODE(store_dir.stat().st_mode) == 0o2770
    assert stat.S_IMODE((store_dir / "drs.sqlite").stat().st_mode) == 0o660

    code, out = as_account(bob, approve)
    assert code == 0, out
    assert "approved by" in out and bob in out

    decided = ApprovalBook(Store.open(store_dir / "drs.sqlite")).get(1)
    assert decided.state == "approved" and decided.requester == Login(alice) and decided.decider == Login(bob)
    for name in os.listdir(store_dir):  # the -wal and -shm bob's SQLite made are the group's too
        info = (store_dir / name).stat()
        assert info.st_gid == os.stat(store_dir).st_gid and stat.S_IMODE(info.st_mode) & 0o007 == 0, name


def test_a_group_that_does_not_exist_is_named_with_how_to_make_it(tmp_path: Path) -> None:
    with pytest.raises(StoreError, match=r"group 'no-such-drs-group' does not exist: as root, `groupadd"):
        from drs_link.store import share_directory

        share_directory(tmp_path / "data", "no-such-drs-group")


def test_the_second_accounts_console_records_exports_and_keeps_chase_files_in_the_shared_data_dir(
    accounts: tuple[str, str, str], place: Path
) -> None:
    """Issue #29 Why-5: the first console made ``recordings/`` 0755 under the 2770 data directory, so the
    second account's console could not start ("Permission denied"). Each console writes its own file;
    every directory made inside the shared one is the group's (2770), whoever made it, whatever the umask."""
    from collections.abc import Callable

    from console.commands.console import _recorder
    from drs_link.ops.audit_log import AuditLog
    from drs_link.store import data_directory, share_directory

    alice, bob, group = accounts
    store_dir = place / "data"
    configs = {user: config_for(place, user, store_dir) for user in (alice, bob)}
    share_directory(store_dir, group)
    Store.open(store_dir / "drs.sqlite").close()
    share_directory(store_dir, group)

    def console_files(user: str) -> Callable[[], int]:
        def work() -> int:
            os.umask(0o022)  # a usual login's: it made recordings/ 0755
            config = load_config(configs[user])
            recorder = _recorder(config)
            recorder.close()
            AuditLog(Store.open(config.store_path)).export(
                config.data.dir / "exports" / f"audit-{user}.jsonl"
            )
            kml = data_directory(config.data.dir / "chase") / f"DRS1-{user}.kml"
            kml.write_text("<kml/>")
            print(recorder.path.name)
            return 0

        return work

    runs = {user: as_account(user, console_files(user)) for user in (alice, bob)}
    assert [code for code, _ in runs.values()] == [0, 0], runs
    for user, (_, out) in runs.items():
        assert f"-{user}-" in out, "named for its account"
    for name in ("recordings", "exports", "chase"):
        info = (store_dir / name).stat()
        assert stat.S_IMODE(info.st_mode) == 0o2770 and info.st_gid == store_dir.stat().st_gid, name
    assert len(list((store_dir / "recordings").iterdir())) == 2


def test_a_directory_made_with_the_old_mode_is_put_right_by_its_owner(tmp_path: Path) -> None:
    from drs_link.store import SHARED_DIR_MODE, data_directory

    tmp_path.chmod(SHARED_DIR_MODE)
    old = tmp_path / "recordings"
    old.mkdir(mode=0o755)
    old.chmod(0o755)
    assert data_directory(old) == old and stat.S_IMODE(old.stat().st_mode) == SHARED_DIR_MODE
    private = tmp_path / "private"
    private.mkdir()
    private.chmod(0o700)
    made = data_directory(private / "exports" / "DRS1")
    assert stat.S_IMODE(made.stat().st_mode) & 0o2000 == 0, "a private data directory stays private"


def test_an_account_outside_the_stores_group_is_told_to_ask_the_admin_not_to_share_it(
    accounts: tuple[str, str, str], place: Path
) -> None:
    alice, _, group = accounts
    store_dir = place / "store"
    share_directory(store_dir, group)
    Store.open(store_dir / "drs.sqlite").close()
    outsider = f"drscarol{os.getpid() % 100000}"
    subprocess.run(["useradd", "-M", "-N", "-s", "/usr/sbin/nologin", outsider], check=True)
    try:

        def open_store() -> int:
            try:
                Store.open(store_dir / "drs.sqlite")
            except StoreError as exc:
                print(exc)
                return 1
            return 0

        code, said = as_account(outsider, open_store)
    finally:
        subprocess.run(["userdel", outsider], check=False, capture_output=True)
    assert code == 1, said
    assert f"the account {outsider} is not in group {group}" in said
    assert f"usermod -aG {group} {outsider}" in said
    assert "shared-store" not in said and "cannot create" not in said
