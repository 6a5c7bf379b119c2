"""The capsule-backend registry: every name the config accepts builds its backend, and no other."""

from __future__ import annotations

import pytest

from drs_link.config import BACKEND_NAMES, parse_config
from drs_link.link.backends.agent import AgentBackend
from drs_link.link.backends.registry import BACKENDS, build_backend
from drs_link.link.backends.stock import StockBackend
from drs_link.link.ssh import CapsuleLink


def test_the_config_accepts_exactly_the_registered_backends() -> None:
    assert sorted(BACKENDS) == sorted(BACKEND_NAMES)


@pytest.mark.parametrize(("name", "kind"), [("stock", StockBackend), ("agent", AgentBackend)])
def test_a_capsule_gets_the_backend_its_config_names(name: str, kind: type) -> None:
    capsule = parse_config({"capsule": [{"name": "DRS1", "host": "h", "backend": name}]}).capsules[0]
    link = CapsuleLink(capsule)
    backend = build_backend(capsule, link)
    assert type(backend) is kind
    assert (backend.capsule, backend.link) == (capsule, link)  # type: ignore[attr-defined]
