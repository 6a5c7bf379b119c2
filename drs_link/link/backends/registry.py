"""A capsule's ``backend`` key to the class that drives its Pi: the one place a backend is chosen.

The CLI, the operations layer, the bench and the tests all build a capsule's backend here, so a new
backend is its module plus one line below (and its name in ``drs_link.config.BACKEND_NAMES``, which
validates the key). The names sit in the config because these classes take the config: the config
importing this registry would close an import cycle and load paramiko with every configuration read.
"""

from __future__ import annotations

from collections.abc import Callable

from drs_link.config import CapsuleConfig
from drs_link.link.backends import CapsuleBackend
from drs_link.link.backends.agent import AgentBackend
from drs_link.link.backends.stock import StockBackend
from drs_link.link.ssh import CapsuleLink

BACKENDS: dict[str, Callable[[CapsuleConfig, CapsuleLink], CapsuleBackend]] = {
    "stock": StockBackend,
    "agent": AgentBackend,
}


def build_backend(capsule: CapsuleConfig, link: CapsuleLink) -> CapsuleBackend:
    """The backend the capsule's configuration names (validated on load, so always registered)."""
    return BACKENDS[capsule.backend](capsule, link)
