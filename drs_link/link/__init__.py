"""The link to a capsule's Pi before release: everything that crosses the SSH connection.

``ssh`` is the connection (host keys verified), ``remote`` every shell command as a fixed template,
``backends`` what drives the release scripts, ``sync`` the data upload, ``storage`` the RAID health,
and ``nmea`` the GNSS state the Pi hears from the microcontroller.
"""

from typing import TYPE_CHECKING

from predictor.lazy_door import lazy_door

if TYPE_CHECKING:
    from . import remote as remote
    from .nmea import (
        GgaSentence as GgaSentence,
        GnssStatus as GnssStatus,
        find_sentence as find_sentence,
        format_gga as format_gga,
        format_rmc as format_rmc,
        nearest_datetime as nearest_datetime,
        parse_sentence as parse_sentence,
        summarise as summarise,
    )
    from .ssh import (
        CapsuleLink as CapsuleLink,
        HostKeyError as HostKeyError,
        enrol_host_key as enrol_host_key,
        fingerprint as fingerprint,
        known_hosts_name as known_hosts_name,
        scan_host_key as scan_host_key,
    )
    from .storage import read_storage as read_storage
    from .sync import Syncer as Syncer, SyncReport as SyncReport, SyncStatus as SyncStatus

__getattr__, __dir__, __all__ = lazy_door(
    __name__,
    {
        "remote": "remote",
        "CapsuleLink": "ssh",
        "GgaSentence": "nmea",
        "GnssStatus": "nmea",
        "HostKeyError": "ssh",
        "SyncReport": "sync",
        "SyncStatus": "sync",
        "Syncer": "sync",
        "enrol_host_key": "ssh",
        "find_sentence": "nmea",
        "fingerprint": "ssh",
        "format_gga": "nmea",
        "format_rmc": "nmea",
        "known_hosts_name": "ssh",
        "nearest_datetime": "nmea",
        "parse_sentence": "nmea",
        "read_storage": "storage",
        "scan_host_key": "ssh",
        "summarise": "nmea",
    },
)
