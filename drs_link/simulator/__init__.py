"""Simulated capsules for tests and the demo: the Pi over SSH, its GPIO and its firmware.

``rockblock.py`` (the Iridium gateway simulator) belongs to the Iridium side of the project.
"""

from drs_link.simulator.capsule_pi import CapsuleSimulator, Faults, SimClock
from drs_link.simulator.firmware import Firmware, GnssSky

__all__ = ["CapsuleSimulator", "Faults", "Firmware", "GnssSky", "SimClock"]
