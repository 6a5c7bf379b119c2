"""The link to a capsule's Pi before release: everything that crosses the SSH connection.

``ssh`` is the connection (host keys verified), ``remote`` every shell command as a fixed template,
``backends`` what drives the release scripts, ``sync`` the data upload, ``storage`` the RAID health,
and ``nmea`` the GNSS state the Pi hears from the microcontroller.
"""

from predictor.lazy_door import lazy_door

__getattr__, __dir__, __all__ = lazy_door(
    __name__,
    {
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
