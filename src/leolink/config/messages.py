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
        if p in _SKIPPED or str(p).startswith(("literal[", "list[", "function-")):
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


def _line(model, err) -> str:
    loc = _clean_loc(model, err["loc"])
    where = ".".join(str(p) for p in loc)
    msg = err["msg"].removeprefix("Value error, ")
    kind = err["type"]
    if kind == "extra_forbidden":
        return f"{where} is not a known key (check the spelling; see docs/config.md)"
    if kind == "missing":
        return f"{where} is required"
    if kind == "value_error":
        return msg
    if kind in ("union_tag_invalid", "union_tag_not_found"):
        tags = err.get("ctx", {}).get("expected_tags", "")
        value = err.get("ctx", {}).get("tag", err.get("input"))
        return f"{where}.kind = {value!r} is not allowed: use one of {tags}"
    info = field_info(model, loc)
    doc = info.description if info is not None and info.description else ""
    meaning = f" ({doc})" if doc else ""
    return f"{where} = {err.get('input')!r} is not allowed: {msg[:1].lower()}{msg[1:]}{meaning}"


def reword(exc: ValidationError, model, source: str = "") -> ConfigError:
    """One :class:`ConfigError` line per validation error, joined by ``; ``."""
    lines = list(dict.fromkeys(_line(model, err) for err in exc.errors()))
    prefix = f"{source}: " if source else ""
    return ConfigError(prefix + "; ".join(lines))
