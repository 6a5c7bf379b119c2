"""The simulated capsules `drs capsule` and `drs sync` are run against: the link's own fixtures, shared."""

from tests.drs_link.conftest import client_key, make_sim  # noqa: F401  (fixtures, found by pytest by name)
