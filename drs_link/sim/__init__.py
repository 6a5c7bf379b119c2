"""Simulators and benches: capsules, their firmware and the Iridium gateway, as real as this machine allows.

``capsule_pi`` is a capsule's Pi behind a real SSH server (``sftp``, ``gpio``, ``keys``), ``firmware``
its microcontroller, ``rockblock`` the RockBLOCK gateway; ``capsule_bench`` and ``mo_bench`` measure
the link and the receiver against them.
"""

from predictor.lazy_door import lazy_door

__getattr__, __dir__, __all__ = lazy_door(
    __name__,
    {
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
