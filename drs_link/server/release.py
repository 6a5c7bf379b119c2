"""The release service: ARM, FIRE and disarm, for whichever operator the kernel says is connected.

A thin service over each desk's ``drs_link.ops.Release``: it sets the request's waivers, polls go/no-go, and
calls ``arm``/``fire``/``finish_go`` of the peer's desk; every rule stays in ``drs_link.ops``. What it
adds is what only a server can know: that a private server is reached by one account alone, so the
two-person rule can never be met there, and that the approving account is another connection's.
"""

from __future__ import annotations

from collections.abc import Callable

from drs_link.errors import ConfigError, RefusedError
from drs_link.ops import (
    ArmStatus,
    GoNoGoReport,
    OnPending,
    Release,
    ReleaseSample,
    ReleaseState,
    SecondOperator,
    TelemetryRecord,
)
from drs_link.server.desks import Desks, PredictorFor
from drs_link.server.paths import readable_path
from drs_link.server.peers import Mode, Peer
from drs_link.server.protocol import ArmRequest, ArmState, FireRequest
from drs_link.server.waivers import WaiverService

PRIVATE_TWO_PERSON = (
    "require_second_operator needs a second account, and only {account} reaches this private server: "
    "run the team's shared server (drs setup server --group GROUP, docs/console.md) and set "
    "[server] socket in each operator's drs.toml"
)
Say = Callable[[str], None]


def two_person_refusal(mode: Mode, peer: Peer, await_approval: bool) -> None:
    """Asking another account's approval of a private server is refused in one line with the way to a
    shared one (nobody else can reach it). Without the ask, the rule refuses as ``drs_link.ops`` words it,
    the same from every face."""
    if mode == "private" and await_approval:
        raise RefusedError(PRIVATE_TWO_PERSON.format(account=peer.account))


class ReleaseService:
    def __init__(
        self, desks: Desks, mode: Mode, waivers: WaiverService, predictor_for: PredictorFor | None = None
    ) -> None:
        self.desks = desks
        self.mode = mode
        self.waivers = waivers
        self.predictor_for = predictor_for

    def _desk(self, peer: Peer, name: str, request: ArmRequest | FireRequest) -> Release:
        release = self.desks.desk(peer).release
        release.state.config.capsule(name)
        if not peer.operator:
            raise ConfigError("operator.name: set [operator] name; every release step is audited with it")
        book = release.state.ops(name).waivers
        if request.held_waivers:  # a console's, audited when it waived: not granted (and audited) again
            book.waivers = list(self.waivers.held(peer, name))
            return release
        book.clear()  # the waivers are the request's own, as one `drs` process had them
        for waive in request.waivers:
            release.waive(name, waive.item, waive.reason)
        return release

    def _poll(self, peer: Peer, release: Release, name: str, weather: tuple[str, ...]) -> GoNoGoReport:
        """The go/no-go poll; the weather files are read only if the peer's account could read them."""
        predict = None
        if weather and self.predictor_for is not None:
            predict = self.predictor_for([readable_path(peer.uid, w) for w in weather], release.state)
        return release.poll_gonogo(name, predict)

    def arm(self, peer: Peer, name: str, request: ArmRequest, say: Say) -> ArmState:
        release = self._desk(peer, name, request)
        say(f"{name}: polling go/no-go (link, microcontroller, GNSS, sync, prediction, gateway)…")
        report = self._poll(peer, release, name, request.weather)
        for line in poll_lines(report):
            say(line)
        return arm_state(name, release.arm(name, report))

    def disarm(self, peer: Peer, name: str, reason: str) -> ArmState:
        status = self.desks.desk(peer).state.ops(name).arming.disarm(reason, any_holder=True)
        return ArmState(name, status.state.value, None, None, 0.0, status.last_disarm_reason)

    def arm_states(self, peer: Peer) -> dict[str, ArmState]:
        """Every capsule's ARM window as ``peer`` sees it (whose it is, and how long it has left)."""
        capsules = self.desks.desk(peer).state.capsules
        return {name: arm_state(name, capsule.arming.seen()) for name, capsule in capsules.items()}

    def fire(self, peer: Peer, name: str, request: FireRequest, say: Say, on_pending: OnPending) -> list[str]:
        """FIRE as the console fires it; an unverified Go is finished instead (``Release.finish_go``)."""
        release = self._desk(peer, name, request)
        second = request.second
        if release.release_state(name) is ReleaseState.GO_SENT:
            say(f"{name}: Go was sent and never verified: finishing it (the first Go's time is kept)…")
            return released_lines(name, release.finish_go(name, request.typed_name))
        two_person_refusal(self.mode, peer, second.await_approval)

        def poll() -> GoNoGoReport:
            say(f"{name}: polling go/no-go again: FIRE needs the verdicts ARM saw")
            report = self._poll(peer, release, name, request.weather)
            for line in poll_lines(report):
                say(line)
            return report

        def sending() -> None:  # said only once every rule has passed, never before a refusal
            say(
                f"{name}: sending Go over SSH (the Go script writes GoGoGo, then shuts the Pi down; about 10 s)…"
            )

        chosen = SecondOperator(second.name, second.waiver, second.await_approval, on_pending)
        return released_lines(name, release.fire(name, request.typed_name, poll, chosen, sending))


def arm_state(name: str, status: ArmStatus) -> ArmState:
    window = status.window
    return ArmState(
        name, status.state.value, window.id if window else None,
        f"{window.until_utc:%H:%M:%S}Z" if window else None, status.remaining_s, status.last_disarm_reason,
        armed_until=status.armed_until, mine=status.mine, holder=status.holder_text(),
    )  # fmt: skip


def poll_lines(report: GoNoGoReport) -> list[str]:
    return [f"  {item.verdict.value:7} {item.title}: {item.detail}" for item in report.items]


def released_lines(name: str, records: list[TelemetryRecord]) -> list[str]:
    note = next((r.data.note for r in records if isinstance(r.data, ReleaseSample)), None) or "Go sent"
    return [f"{name}: {note}; release A opens about 32 s after Go"]
