"""Errors the capsule link reports to an operator: one clear line each, never a traceback."""


class LinkError(Exception):
    """Base of every drs_link error meant for an operator."""


class ConfigError(LinkError):
    """The configuration file is missing, malformed, or names an unknown key or a bad value."""


class StoreError(LinkError):
    """The durable store cannot be written (full disk, read-only, corrupt): nothing was acknowledged."""


class RefusedError(LinkError):
    """A command was refused by the domain layer because its preconditions or confirmation do not hold."""
