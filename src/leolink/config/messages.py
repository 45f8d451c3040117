"""Pydantic validation errors reworded as leolink's one-line messages.

Every message names the key as ``--set`` spells it, the value and what is allowed, e.g.
``link.bandwidth_hz = 0.0 is not allowed: input should be greater than 0 (downlink
bandwidth [Hz])``.
"""

from __future__ import annotations

import typing

from pydantic import BaseModel, ValidationError

from leolink.errors import ConfigError

__all__ = ["field_info", "reword"]

_SKIPPED = ("function-after", "function-before", "function-wrap", "tagged-union")
#: loc parts naming the branch of a union (``float | Literal['auto']``), not a key.
_BRANCHES = ("float", "int", "str", "bool", "list", "dict")
_BRANCH_PREFIXES = ("literal[", "list[", "function-", "constrained-", "json-or-python")


def _models_in(annotation) -> list[type[BaseModel]]:
    """Every pydantic model inside an annotation (through lists, unions, Annotated)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    return [m for arg in typing.get_args(annotation) for m in _models_in(arg)]


def _tag(model) -> str | None:
    kind = model.model_fields.get("kind")
    args = typing.get_args(kind.annotation) if kind is not None else ()
    return args[0] if len(args) == 1 and isinstance(args[0], str) else None


def _clean_loc(model, loc) -> list:
    """The loc without pydantic's internal parts and union tags: ``population.0.count``."""
    parts, candidates = [], [model]
    for p in loc:
        if isinstance(p, int):
            parts.append(p)
            continue
        if p in _SKIPPED or p in _BRANCHES or str(p).startswith(_BRANCH_PREFIXES):
            continue
        tagged = [m for m in candidates if _tag(m) == p]
        if tagged and len(candidates) > 1:  # a discriminated-union tag, not a key
            candidates = tagged
            continue
        parts.append(p)
        found = [m.model_fields[p] for m in candidates if p in m.model_fields]
        candidates = _models_in(found[0].annotation) if found else []
    return parts


def field_info(model, loc):
    """The pydantic ``FieldInfo`` at a cleaned ``loc`` (None if not a field)."""
    candidates, info = [model], None
    for p in loc:
        if isinstance(p, int):
            continue
        found = [m.model_fields[p] for m in candidates if p in m.model_fields]
        if not found:
            return None
        info = found[0]
        candidates = _models_in(info.annotation)
    return info


def _special(model, where, loc, err) -> str | None:
    """The line of an error that is not about a value's type or bounds, else None."""
    msg = err["msg"].removeprefix("Value error, ")
    kind = err["type"]
    if kind == "extra_forbidden":
        return f"{where} is not a known key (check the spelling; see docs/config.md)"
    if kind == "missing":
        return f"{where} is required"
    if kind == "value_error":  # a validator's own message; name the key if it does not
        named = not loc or msg.startswith(str(loc[0]))
        return msg if named else f"{where}: {msg}"
    if kind in ("union_tag_invalid", "union_tag_not_found"):
        value, tags = err.get("ctx", {}).get("tag", err.get("input")), _tags(model, loc)
        if not isinstance(value, dict | str):  # not a table at all
            return f"{where} = {value!r} is not allowed: use a table with kind one of {tags}"
        return f"{where}.kind = {value!r} is not allowed: use one of {tags}"
    return None


def _tags(model, loc) -> str:
    """The ``kind`` tags of the union at ``loc``, quoted (pydantic gives them only for an
    unknown tag, not for a missing one)."""
    info = field_info(model, loc)
    models = _models_in(info.annotation) if info is not None else []
    return ", ".join(repr(t) for t in dict.fromkeys(_tag(m) for m in models) if t is not None)


def _lines(model, errors) -> list[str]:
    """One line per key: the branches of a union (``float | 'auto'``) are joined by "or"."""
    lines: dict[str, list] = {}
    for err in errors:
        loc = _clean_loc(model, err["loc"])
        where = ".".join(str(p) for p in loc)
        special = _special(model, where, loc, err)
        if special is not None:
            lines.setdefault(special, [])
            continue
        msg = err["msg"]
        head = f"{where} = {err.get('input')!r} is not allowed: "
        lines.setdefault(head, [loc]).append(msg[:1].lower() + msg[1:])
    out = []
    for head, parts in lines.items():
        if not parts:
            out.append(head)
            continue
        info = field_info(model, parts[0])
        doc = f" ({info.description})" if info is not None and info.description else ""
        out.append(head + ", or ".join(dict.fromkeys(parts[1:])) + doc)
    return out


def reword(exc: ValidationError, model, source: str = "") -> ConfigError:
    """One :class:`ConfigError` line per validation error, joined by ``; ``."""
    lines = _lines(model, exc.errors())
    prefix = f"{source}: " if source else ""
    return ConfigError(prefix + "; ".join(lines))
