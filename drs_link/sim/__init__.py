"""Simulators and benches: capsules, their firmware and the Iridium gateway, as real as this machine allows.

``capsule_pi`` is a capsule's Pi behind a real SSH server (``sftp``, ``gpio``, ``keys``), ``firmware``
its microcontroller, ``rockblock`` the RockBLOCK gateway; ``capsule_bench`` and ``mo_bench`` measure
the link and the receiver against them.
"""

from typing import TYPE_CHECKING

from predictor.lazy_door import lazy_door

if TYPE_CHECKING:
    from . import capsule_bench as capsule_bench, mo_bench as mo_bench
    from .capsule_pi import CapsuleSimulator as CapsuleSimulator, Faults as Faults, SimClock as SimClock
    from .firmware import Firmware as Firmware, GnssSky as GnssSky
    from .keys import write_ed25519 as write_ed25519
    from .rockblock import (
        SimulatedCapsule as SimulatedCapsule,
        SimulatedRockblock as SimulatedRockblock,
        generate_test_keys as generate_test_keys,
        post_mo as post_mo,
    )

__getattr__, __dir__, __all__ = lazy_door(
    __name__,
    {
        "capsule_bench": "capsule_bench",
        "mo_bench": "mo_bench",
        "CapsuleSimulator": "capsule_pi",
        "Faults": "capsule_pi",
        "Firmware": "firmware",
        "GnssSky": "firmware",
        "SimClock": "capsule_pi",
        "SimulatedCapsule": "rockblock",
        "SimulatedRockblock": "rockblock",
        "generate_test_keys": "rockblock",
        "post_mo": "rockblock",
        "write_ed25519": "keys",
    },
)
