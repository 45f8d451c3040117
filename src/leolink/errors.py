"""Exceptions that leolink raises on purpose (the CLI prints them as one line)."""


class LeolinkError(Exception):
    """Base class of every error leolink raises on purpose."""


class ConfigError(LeolinkError, ValueError):
    """A config value outside what leolink accepts."""


def require_at_least(field, value, low, meaning):
    """Raise :class:`ConfigError` unless ``value >= low``."""
    if not value >= low:
        raise ConfigError(f"{field} = {value!r} is not allowed; use a value >= {low} ({meaning})")
