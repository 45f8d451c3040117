"""``--set section.key=value`` overrides, applied to the config's dict before validation."""

from __future__ import annotations

import re
import tomllib

from leolink.errors import ConfigError

__all__ = ["MAX_DEPTH", "apply_overrides", "loads_toml"]

#: Deepest nesting of tables and arrays a config may have (leolink's own is 3 deep).
MAX_DEPTH = 32
_INT_DIGITS = re.compile(r"\d{4300,}")


def loads_toml(text: str, what: str) -> dict:
    """``tomllib.loads(text)`` with the limits of the edge, each one :class:`ConfigError`
    line naming ``what`` (a file, a ``--set`` key): nesting deeper than :data:`MAX_DEPTH`
    (a RecursionError deeper still), an integer of more than 4,300 digits (Python's limit
    for integer text). ``tomllib.TOMLDecodeError`` passes through."""
    try:
        data = tomllib.loads(text)
    except RecursionError:
        data = None
    except ValueError as exc:
        if isinstance(exc, tomllib.TOMLDecodeError):
            raise
        match = _INT_DIGITS.search(text)
        where = match.start() if match and "\n" in text else None
        line = "" if where is None else f" (line {text.count(chr(10), 0, where) + 1})"
        raise ConfigError(
            f"{what}: an integer of more than 4,300 digits{line} is not allowed; no leolink "
            "value needs more than 20"
        ) from None
    if data is None or _depth(data) > MAX_DEPTH:
        raise ConfigError(
            f"{what}: tables or arrays nested more than {MAX_DEPTH} deep are not allowed"
        )
    return data


def _depth(node) -> int:
    """Nesting depth of dicts and lists (iterative: no recursion limit to hit)."""
    deepest, stack = 0, [(node, 0)]
    while stack:
        item, depth = stack.pop()
        if isinstance(item, dict | list):
            deepest = max(deepest, depth + 1)
            values = item.values() if isinstance(item, dict) else item
            stack.extend((v, depth + 1) for v in values)
    return deepest


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
            parsed = loads_toml(f"v = {raw.strip()}", f"--set {key.strip()}")
        except tomllib.TOMLDecodeError:
            parsed = {"v": raw.strip()}
        if len(parsed) > 1:  # "5\nother = 1": TOML after the value, which would be dropped
            raise ConfigError(
                f"--set {item!r} is not allowed: give one value; set another key with another --set"
            )
        value = parsed["v"]
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
