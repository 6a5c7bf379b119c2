"""A capsule's ``backend`` key to the class that drives its Pi: the one place a backend is chosen.

The CLI, the operations layer, the bench and the tests all build a capsule's backend here. A backend
is a module of this package that names its class ``BACKEND``; the registry finds it by its module
name, so a new backend is its module and nothing else (``drs_link.link.backends.backend_names``, which
the config validates the key against, lists the modules without importing them). The module is
imported only when a capsule of that backend is built, so reading the config, or ``drs --help``,
does not load the backends (nor paramiko, which the agent backend needs).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import TYPE_CHECKING

from drs_link.link import backends
from drs_link.link.backends import CapsuleBackend

if TYPE_CHECKING:
    from drs_link.config import CapsuleConfig
    from drs_link.link.ssh import CapsuleLink

BACKEND_ATTRIBUTE = "BACKEND"
"""The name under which each backend module declares its class."""


def backend_class(name: str) -> Callable[[CapsuleConfig, CapsuleLink], CapsuleBackend]:
    """The class the backend module ``name`` declares as ``BACKEND``."""
    module = importlib.import_module(f"{backends.__name__}.{name}")
    return getattr(module, BACKEND_ATTRIBUTE)


def build_backend(capsule: CapsuleConfig, link: CapsuleLink) -> CapsuleBackend:
    """The backend the capsule's configuration names (validated on load, so always a backend module)."""
    return backend_class(capsule.backend)(capsule, link)
