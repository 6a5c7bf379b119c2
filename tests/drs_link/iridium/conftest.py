"""The receiver processes a test starts, killed after it whatever happened (the receiver tests and the
store-fault tests both start real `drs mo serve` processes)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING

import pytest

if TYPE_CHECKING:
    from tests.drs_link.iridium.test_receiver_process import Receiver


@pytest.fixture
def receivers() -> Iterator[list[Receiver]]:
    started: list[Receiver] = []
    yield started
    for receiver in started:
        if receiver.process.poll() is None:
            receiver.process.kill()
            receiver.process.wait(timeout=10)
