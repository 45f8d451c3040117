"""``docs/config.md``: every config key with its type, default, bounds and meaning.

Generated from the models, registries included, by ``python -m leolink.config.reference``;
a test keeps the file in step with the code.
"""

from __future__ import annotations

import typing
from typing import Annotated, Literal

from pydantic import BaseModel

from leolink.config import config_model
from leolink.config.kinds import OutputSection, SelectorSection
from leolink.registry import REGISTRIES

__all__ = ["reference_markdown"]

_HEADER = [
    "# Config reference",
    "",
    "One TOML file describes a run (`configs/paper.toml`, the example `paper`, is the",
    "paper's Table). Every key is optional; the defaults are the paper's Table (its",
    "534.1 x 170.5 km ROI included), so a file holding only `[run]` and `duration_s = 60.0`",
    "runs the paper's pass with one static UT at the ROI centre. Override any key from the",
    "command line with `--set section.key=value` (lists of tables by index:",
    "`population.0.count=3`).",
    "A section with a choice (`terminal.kind`, `atmosphere.model`, `controller.policy`)",
    "has one table per choice, named after it (`[terminal.upa]`); only the chosen one is",
    "used. Generated from the models and registries by `python -m leolink.config.reference`.",
    "",
]


def _type_text(annotation) -> str:
    """``float | None`` -> ``float or none``, ``Literal['a', 'b']`` -> ``'a', 'b'``."""
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin is Literal:
        return ", ".join(repr(a) for a in args)
    if origin is list:
        return f"list of {_type_text(args[0])}"
    if origin is Annotated:
        return _type_text(args[0])
    if args:  # a union
        return " or ".join("none" if a is type(None) else _type_text(a) for a in args)
    return getattr(annotation, "__name__", str(annotation))


def _inner_metadata(annotation) -> list:
    """Constraints inside an annotation (list items, union members: ``Annotated[float, ...]``)."""
    out: list = []
    for arg in typing.get_args(annotation):
        out += getattr(arg, "metadata", [])  # a FieldInfo inside Annotated
        out += _inner_metadata(arg)
    return out


def _allowed_text(info) -> str:
    bounds = []
    for m in [*info.metadata, *_inner_metadata(info.annotation)]:
        for name, sym in (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<=")):
            value = getattr(m, name, None)
            if value is not None:
                bounds.append(f"{sym} {value:g}")
    return ", ".join(bounds)


def _rows(model, skip=()):
    lines = ["| key | type | default | allowed | meaning |", "|---|---|---|---|---|"]
    for key, info in model.model_fields.items():
        if (
            key in skip
            or isinstance(info.annotation, type)
            and issubclass(info.annotation, BaseModel)
        ):
            continue
        default = info.default_factory() if info.default_factory else info.default
        lines.append(
            f"| `{key}` | {_type_text(info.annotation)} | `{default!r}` | "
            f"{_allowed_text(info)} | {info.description or ''} |"
        )
    return lines + [""]


def _tables(name, model, skip):
    """The nested tables of a section that are not per-entry tables (``[controller.rlf]``)."""
    lines = []
    for key, info in model.model_fields.items():
        sub = info.annotation
        if key in skip or not (isinstance(sub, type) and issubclass(sub, BaseModel)):
            continue
        lines += [f"### `[{name}.{key}]`: {info.description or ''}", "", *_rows(sub)]
    return lines


def _section(name, model):
    if isinstance(model, type) and issubclass(model, SelectorSection):
        entries = {e for reg in model.registries.values() for e in reg.names()}
        lines = [f"## `[{name}]`", "", *_rows(model), *_tables(name, model, entries)]
        for key, reg in model.registries.items():
            for entry in reg.names():
                which = f" ({key} = '{entry}')" if len(model.registries) > 1 else ""
                lines += [f"### `[{name}.{entry}]`{which}: {reg[entry].doc}", ""]
                cfg = reg[entry].config
                lines += _rows(cfg) if cfg.model_fields else ["(no keys)", ""]
        return lines
    if isinstance(model, type) and issubclass(model, OutputSection):
        lines = [f"## `[{name}]`", "", "One table per output; each has `enabled`.", ""]
        for entry in model.registry.names():
            lines += [f"### `[{name}.{entry}]`: {model.registry[entry].doc}", ""]
            lines += _rows(model.registry[entry].config)
        return lines
    return [f"## `[{name}]`", "", *_rows(model), *_tables(name, model, ())]


def _populations():
    reg = REGISTRIES["population.kind"]
    lines = [
        "## `[[population]]`",
        "",
        "`kind` chooses the motion model (default `'static'`).",
        "Every kind may also carry `terminal`, its UTs' antenna: a table shaped as",
        "`[terminal]` (`[population.terminal] kind = ...` and",
        "`[population.terminal.<kind>]`); without it, the `[terminal]` section.",
        "",
    ]
    for entry in reg.names():
        lines += [f"### `kind = '{entry}'`: {reg[entry].doc}", "", *_rows(reg[entry].config)]
    return lines


def reference_markdown() -> str:
    """Every config key as Markdown (``docs/config.md``)."""
    lines = list(_HEADER)
    for name, info in config_model().model_fields.items():
        if name == "source":
            continue
        lines += _populations() if name == "population" else _section(name, info.annotation)
    return "\n".join(lines).rstrip() + "\n"


if __name__ == "__main__":  # python -m leolink.config.reference > docs/config.md
    print(reference_markdown(), end="")
