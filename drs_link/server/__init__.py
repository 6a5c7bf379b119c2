"""The operations server: one process holds the store, the capsule links and the gateway credentials,
and every face acts through it (issue #29).

``app`` is ``drs server`` (aiohttp on a Unix socket); ``peers`` who a connection is, from the kernel
(``SO_PEERCRED``) and the server's own ``[[operator]]`` list; ``desks`` one ``drs_link.ops`` engine per
operator; ``release`` (ARM, FIRE, disarm), ``capsules`` (status, power-on, reset, a recorded fall, the
release authority, enrolment), ``iridium`` and ``approvals`` the thin services over them; ``telemetry``
the capsules polled once for every console and pushed to each; ``chase`` what ``drs chase`` sends; and
for a console's desk ``waivers``, ``checklists``, ``history`` (the audit, a session's start and loss) and
``views`` (recovery, Iridium, PARACHUTE overrides); ``protocol`` the typed, versioned messages;
``client`` the faces' one client with verbs, ``desk`` a console's verbs whose answers
(``desk_views``) are the operations layer's values; ``private`` an account's own server, started on demand.
"""

from typing import TYPE_CHECKING

from predictor.lazy_door import lazy_door

if TYPE_CHECKING:
    from . import iridium as iridium
    from .app import OperationsServer as OperationsServer
    from .client import (
        TIMEOUT_S as TIMEOUT_S,
        Capsule as Capsule,
        Client as Client,
        raise_failure as raise_failure,
    )
    from .desk import Desk as Desk
    from .desk_views import (
        DeskView as DeskView,
        HistoryView as HistoryView,
        ParachuteView as ParachuteView,
    )
    from .desks import PredictorFor as PredictorFor
    from .peers import (
        Peer as Peer,
        Roster as Roster,
        account_of as account_of,
        check_own_file as check_own_file,
        peer_uid as peer_uid,
    )
    from .private import (
        InProcessServer as InProcessServer,
        ensure_private_server as ensure_private_server,
        private_socket as private_socket,
    )
    from .protocol import (
        MAX_BODY_BYTES as MAX_BODY_BYTES,
        PROTOCOL as PROTOCOL,
        ApprovalView as ApprovalView,
        ArmState as ArmState,
        CapsuleStatus as CapsuleStatus,
        DescentView as DescentView,
        Done as Done,
        Event as Event,
        Failure as Failure,
        Hello as Hello,
        MtSendRequest as MtSendRequest,
        MtView as MtView,
        Pending as Pending,
        RecoveryRequest as RecoveryRequest,
        ReleaseView as ReleaseView,
        Second as Second,
        iso_utc as iso_utc,
    )
    from .recovery import LiveFor as LiveFor
    from .release import PRIVATE_TWO_PERSON as PRIVATE_TWO_PERSON
    from .telemetry import POLL_PERIOD_S as POLL_PERIOD_S, Periods as Periods

__getattr__, __dir__, __all__ = lazy_door(
    __name__,
    {
        "ApprovalView": "protocol",
        "Capsule": "client",
        "TIMEOUT_S": "client",
        "CapsuleStatus": "protocol",
        "ArmState": "protocol",
        "Event": "protocol",
        "InProcessServer": "private",
        "Pending": "protocol",
        "Client": "client",
        "DescentView": "protocol",
        "Done": "protocol",
        "Failure": "protocol",
        "Hello": "protocol",
        "MAX_BODY_BYTES": "protocol",
        "MtSendRequest": "protocol",
        "MtView": "protocol",
        "ReleaseView": "protocol",
        "Desk": "desk",
        "DeskView": "desk_views",
        "HistoryView": "desk_views",
        "ParachuteView": "desk_views",
        "OperationsServer": "app",
        "PRIVATE_TWO_PERSON": "release",
        "POLL_PERIOD_S": "telemetry",
        "Periods": "telemetry",
        "PROTOCOL": "protocol",
        "RecoveryRequest": "protocol",
        "LiveFor": "recovery",
        "Peer": "peers",
        "PredictorFor": "desks",
        "Roster": "peers",
        "Second": "protocol",
        "account_of": "peers",
        "iridium": "iridium",
        "iso_utc": "protocol",
        "check_own_file": "peers",
        "ensure_private_server": "private",
        "peer_uid": "peers",
        "private_socket": "private",
        "raise_failure": "client",
    },
)
