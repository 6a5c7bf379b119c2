"""The capsule-backend registry: every name the config accepts builds its backend, and no other."""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import subprocess
import sys

import pytest

from drs_link.config import parse_config
from drs_link.errors import ConfigError
from drs_link.link.backends import SUPPORT_MODULES, CapsuleBackend, backend_names
from drs_link.link.backends.agent import AgentBackend
from drs_link.link.backends.registry import BACKEND_ATTRIBUTE, backend_class, build_backend
from drs_link.link.backends.stock import StockBackend
from drs_link.link.ssh import CapsuleLink


def test_the_backends_are_the_package_modules_that_are_not_support_modules() -> None:
    assert set(backend_names()) == {"stock", "agent"}
    assert not set(backend_names()) & SUPPORT_MODULES


@pytest.mark.parametrize("name", backend_names())
def test_every_backend_module_declares_a_class_that_implements_the_interface(name: str) -> None:
    """A module in the package that is neither a support module nor declares ``BACKEND`` fails here."""
    module = importlib.import_module(f"drs_link.link.backends.{name}")
    kind = getattr(module, BACKEND_ATTRIBUTE, None)
    assert inspect.isclass(kind), f"drs_link/link/backends/{name}.py declares no {BACKEND_ATTRIBUTE} class"
    protocol = {n for n, member in vars(CapsuleBackend).items() if inspect.isfunction(member)}
    assert protocol <= set(dir(kind)), f"{kind.__name__} lacks {sorted(protocol - set(dir(kind)))}"
    assert backend_class(name) is kind


def test_the_support_modules_exist() -> None:
    """A support module renamed or removed must leave the list, or its old name would stay reserved."""
    for name in SUPPORT_MODULES:
        assert importlib.util.find_spec(f"drs_link.link.backends.{name}") is not None


@pytest.mark.parametrize(("name", "kind"), [("stock", StockBackend), ("agent", AgentBackend)])
def test_a_capsule_gets_the_backend_its_config_names(name: str, kind: type) -> None:
    capsule = parse_config({"capsule": [{"name": "DRS1", "host": "h", "backend": name}]}).capsules[0]
    link = CapsuleLink(capsule)
    backend = build_backend(capsule, link)
    assert type(backend) is kind
    assert (backend.capsule, backend.link) == (capsule, link)  # type: ignore[attr-defined]


@pytest.mark.parametrize("name", ["registry", "authority", "pi_agent", "nosuch"])
def test_the_config_refuses_a_name_that_is_not_a_backend_naming_the_default_first(name: str) -> None:
    with pytest.raises(ConfigError, match=r"capsule\[0\]\.backend: .* is not one of 'stock', 'agent'"):
        parse_config({"capsule": [{"name": "DRS1", "host": "h", "backend": name}]})


def test_reading_the_config_loads_no_backend_and_not_paramiko() -> None:
    """The config lists the backends by module name only: no cycle, and no paramiko on every read."""
    code = (
        "import sys; from drs_link.config import parse_config; "
        "parse_config({'capsule': [{'name': 'DRS1', 'host': 'h', 'backend': 'agent'}]}); "
        "print(sorted(m for m in sys.modules if m.startswith('drs_link.link.backends.') or m == 'paramiko'))"
    )
    loaded = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert loaded.strip() == "[]"
