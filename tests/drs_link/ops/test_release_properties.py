"""Random operator sequences never make the state machine send Go when it should not."""

from __future__ import annotations

import tempfile
from pathlib import Path

from hypothesis import settings, strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, precondition, rule

from drs_link.config import CapsuleConfig
from drs_link.errors import LinkError, RefusedError
from drs_link.link.backends import GoResult
from drs_link.ops.capsule import ConfirmationToken, ReleaseState, ReleaseStateMachine
from drs_link.store import Store
from tests.clock import ManualClock

from .test_release_state_machine import START, InProcessPi


class ReleaseSequences(RuleBasedStateMachine):
    def __init__(self) -> None:
        super().__init__()
        # Thousands of fsyncs per run: keep the store in RAM when the machine has /dev/shm.
        self._tmp = tempfile.TemporaryDirectory(dir="/dev/shm" if Path("/dev/shm").is_dir() else None)
        self.clock = ManualClock(START)
        self.pi = InProcessPi(self.clock, nmea_after_s=0.0)
        self.machine = ReleaseStateMachine(
            Store.open(Path(self._tmp.name) / "drs.sqlite"),
            CapsuleConfig(name="DRS1", host="drs1.local"),
            self.pi,
            "EL",
            clock=self.clock,
            sleep=self.clock.advance,
        )
        self.tokens: list[ConfirmationToken] = []
        self.go_calls_seen = 0
        self.tokens_that_sent_go: set[str] = set()
        self.session_of_token: dict[str, str | None] = {}

    def teardown(self) -> None:
        self._tmp.cleanup()

    @rule(confirmed=st.booleans())
    def power_on(self, confirmed: bool) -> None:
        try:
            self.machine.power_on(confirmed)
        except RefusedError:
            assert not confirmed or self.machine.record().state in (
                ReleaseState.RELEASED,
                ReleaseState.GO_SENT,
            )

    @rule()
    def power_on_and_look(self) -> None:
        """The usual operator path as one step, so the search reaches Go-able states often."""
        self.power_on(True)
        self.machine.check_microcontroller()

    @rule(seconds=st.sampled_from([0.0, 1.0, 30.0, 59.0, 61.0, 120.0]))
    def wait(self, seconds: float) -> None:
        self.clock.advance(seconds)

    @rule()
    def look_at_the_serial_log(self) -> None:
        self.machine.check_microcontroller()

    @rule(typed=st.sampled_from(["DRS1", "DRS1", "DRS2", "drs1"]))
    def confirm(self, typed: str) -> None:
        try:
            token = self.machine.confirm(typed)
        except RefusedError:
            return
        self.tokens.append(token)
        self.session_of_token[token.value] = self.machine.record().session

    @rule(drop_before_write=st.booleans())
    def link_quality(self, drop_before_write: bool) -> None:
        self.pi.go_outcome = (
            GoResult(False, False, True, None, "")
            if drop_before_write
            else GoResult(True, True, True, None, "Dropping in 30 seconds!\nShutting down...\n")
        )

    @precondition(lambda self: self.tokens)
    @rule(index=st.integers(min_value=0), forge=st.booleans())
    def go(self, index: int, forge: bool) -> None:
        token = self.tokens[index % len(self.tokens)]
        if forge:
            token = ConfirmationToken(token.value + "x", token.capsule, token.minted_at)
        before = self.machine.record()
        calls_before = self.pi.calls.count("go")
        try:
            self.machine.go(token)
        except (RefusedError, LinkError):
            pass
        sent = self.pi.calls.count("go") > calls_before
        if sent:
            age = (self.clock() - token.minted_at).total_seconds()
            assert not forge
            assert token.value not in self.tokens_that_sent_go, "one confirmation sent Go twice"
            self.tokens_that_sent_go.add(token.value)
            assert before.state in (ReleaseState.POWERED, ReleaseState.GO_SENT)
            assert before.nmea_seen_at is not None and 0 <= age <= 60
            assert self.session_of_token[token.value] == before.session, "token of an earlier power-on"

    @invariant()
    def released_capsules_never_get_another_go(self) -> None:
        calls = self.pi.calls.count("go")
        if self.machine.record().state is ReleaseState.RELEASED and self.go_calls_seen:
            assert calls == self.go_calls_seen
        if self.machine.record().state is ReleaseState.RELEASED and not self.go_calls_seen:
            self.go_calls_seen = calls

    @invariant()
    def go_is_only_sent_after_a_power_on(self) -> None:
        if self.pi.calls.count("go"):
            assert "power_on" in self.pi.calls


ReleaseSequences.TestCase.settings = settings(max_examples=300, stateful_step_count=20, deadline=None)
test_random_operator_sequences_are_safe = ReleaseSequences.TestCase
