"""``--set section.key=value`` overrides, applied to the config's dict before validation."""

from __future__ import annotations

import tomllib

from leolink.errors import ConfigError

__all__ = ["apply_overrides"]


def apply_overrides(data: dict, overrides: list[str] | None) -> dict:
    """Apply ``section.key=value`` overrides (value parsed as TOML, else a string).

    Lists of tables are indexed: ``population.0.speed_m_s=30``.
    """
    data = _deepcopy(data)
    for item in overrides or []:
        key, sep, raw = item.partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"--set {item!r} is not allowed: use section.key=value")
        try:
            value = tomllib.loads(f"v = {raw.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            value = raw.strip()
        node = data
        parts = key.strip().split(".")
        for depth, part in enumerate(parts[:-1]):
            if isinstance(node, list):
                _check_table_list(node, item, ".".join(parts[:depth]))
                node = _index(node, part, key)
            else:
                node = node.setdefault(part, {})
            if not isinstance(node, dict | list):
                raise ConfigError(
                    f"--set {item!r} is not allowed: {part!r} holds a value, not a table"
                )
        if isinstance(node, list):
            _check_table_list(node, item, ".".join(parts[:-1]))
            raise ConfigError(f"--set {item!r}: give an index and a key, e.g. population.0.count=3")
        node[parts[-1]] = value
    return data


def _check_table_list(node: list, item: str, name: str):
    if node and not isinstance(node[0], dict):
        raise ConfigError(
            f"--set {item!r} is not allowed: {name} is a list; set it whole, e.g. {name}=[0, 5]"
        )


def _index(node: list, part: str, key: str):
    if not part.isdigit() or int(part) >= len(node):
        raise ConfigError(f"--set {key}: index {part!r} is not allowed; use 0..{len(node) - 1}")
    return node[int(part)]


def _deepcopy(obj):
    if isinstance(obj, dict):
        return {k: _deepcopy(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_deepcopy(v) for v in obj]
    return obj
