"""Health of the capsule's data store: the RAID1 mount's usage (``df``) and the array (``/proc/mdstat``).

The data flown in the capsule is the reason it exists, so a degraded mirror ([UUU_]) or a nearly
full mount must be visible before release. The parsers take command output as text and never
raise on odd input: what cannot be read is reported as unknown.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from drs_link.errors import LinkError
from drs_link.link import remote
from drs_link.link.ssh import CapsuleLink

_MD_LINE = re.compile(r"^(md\d+)\s*:\s*(\S+)\s+(?:\(\S+\)\s+)?(\S+)?\s*(.*)$")
_MEMBERS = re.compile(r"\[(\d+)/(\d+)\]\s*\[([U_]+)\]")


@dataclass(frozen=True)
class DiskUsage:
    filesystem: str
    total_bytes: int
    used_bytes: int
    available_bytes: int
    mount: str


@dataclass(frozen=True)
class RaidArray:
    device: str
    active: bool
    level: str | None
    devices_total: int | None
    devices_up: int | None
    member_map: str | None

    @property
    def healthy(self) -> bool:
        return (
            self.active
            and self.member_map is not None
            and "_" not in self.member_map
            and self.devices_total == self.devices_up
        )

    @property
    def state(self) -> str:
        if not self.active:
            return "inactive"
        if self.member_map is None:
            return "unknown"
        return "healthy" if self.healthy else "degraded"


@dataclass(frozen=True)
class StorageStatus:
    usage: DiskUsage | None
    raid: RaidArray | None

    def as_dict(self) -> dict[str, object]:
        usage, raid = self.usage, self.raid
        return {
            "mount": usage.mount if usage else None,
            "total_bytes": usage.total_bytes if usage else None,
            "used_bytes": usage.used_bytes if usage else None,
            "available_bytes": usage.available_bytes if usage else None,
            "raid_device": f"/dev/{raid.device}" if raid else None,
            "raid_state": raid.state if raid else "missing",
            "raid_members": raid.member_map if raid else None,
        }


def parse_df(text: str) -> DiskUsage | None:
    """``df -P -B1 MOUNT`` output → usage of that one mount (None when unreadable)."""
    for line in text.splitlines()[1:]:
        parts = line.split()
        if len(parts) >= 6 and all(p.isdigit() for p in parts[1:4]):
            return DiskUsage(parts[0], int(parts[1]), int(parts[2]), int(parts[3]), " ".join(parts[5:]))
    return None


def parse_mdstat(text: str, device: str = "md0") -> RaidArray | None:
    """One array from ``/proc/mdstat``; ``[4/3] [UUU_]`` is a degraded four-way mirror."""
    lines = text.splitlines()
    for index, line in enumerate(lines):
        match = _MD_LINE.match(line.strip())
        if not match or match.group(1) != device:
            continue
        active = match.group(2) == "active"
        level = match.group(3) if active else None
        members = None
        for follow in lines[index + 1 : index + 3]:
            members = _MEMBERS.search(follow) or members
        if members is None:
            return RaidArray(device, active, level, None, None, None)
        return RaidArray(
            device, active, level, int(members.group(1)), int(members.group(2)), members.group(3)
        )
    return None


def read_storage(link: CapsuleLink, mount: str, raid_device: str) -> StorageStatus:
    result = link.run(remote.storage_report(mount))
    if result.link_dropped or result.timed_out:
        raise LinkError(f"{link.capsule.name}: the link failed while reading storage status")
    df_text, _, mdstat_text = result.stdout.partition("--mdstat--\n")
    return StorageStatus(parse_df(df_text), parse_mdstat(mdstat_text, raid_device.rsplit("/", 1)[-1]))
