"""Config sections built from the registries of the pluggable kinds.

Three shapes, each validated once, when the config is loaded:

- a *selector* section: one key chooses an entry, and every entry has its own table
  named after it, e.g. ``[terminal] kind = "upa"`` with ``[terminal.upa] n_x = 24``
  (tables of the kinds not chosen may stay, so ``--set terminal.kind=...`` switches);
- the *population* list: each ``[[population]]`` table is the parameter model of its
  ``kind`` (a discriminated union; ``kind`` defaults to ``"static"``);
- the *output* section: one table per sink, each with ``enabled``.

The models are rebuilt when an entry is registered (``leolink.registry.generation``),
so a kind added by a plugin module is known to the loader, to ``leolink validate`` and
to ``docs/config.md`` without any edit here. Out-of-tree plugins are found through the
entry-point group :data:`PLUGIN_GROUP` (``leolink.plugins``): each entry point names a
module (or an object in one) whose import registers kinds; :func:`load_owners` imports
them once, before any schema is built, so an installed package's kinds are usable from
``leolink run ... --set terminal.kind=<it>`` with no other step.
"""

from __future__ import annotations

import functools
import importlib
import importlib.metadata
from typing import Annotated, Any, ClassVar, Literal, Union

from pydantic import Discriminator, Field, Tag, create_model

from leolink.config.schema import Section
from leolink.errors import ConfigError
from leolink.registry import REGISTRIES, Params, Registry, generation

__all__ = [
    "OWNERS",
    "PLUGIN_GROUP",
    "OutputSection",
    "SelectorSection",
    "load_owners",
    "population_union",
    "terminal_section",
]

#: Modules that own a registry or register entries (imported before a schema is built).
OWNERS = (
    "leolink.antenna.terminal",
    "leolink.antenna.steering",
    "leolink.ephemeris_error",
    "leolink.io.ephemeris_sink",
    "leolink.link.atmosphere",
    "leolink.sim.handover.policies",
    "leolink.sim.handover.trigger_policies",
    "leolink.sim.handover.slotted",
    "leolink.sim.mobility.populations",
    "leolink.io.tracks",
    "leolink.io.sinks",
    "leolink.sim.beams.selectors",
    "leolink.sim.beams.scheduler",
    "leolink.link.precoder",
)


#: Entry-point group of out-of-tree plugins (``[project.entry-points."leolink.plugins"]``).
PLUGIN_GROUP = "leolink.plugins"


def load_owners():
    """Import the modules that fill the registries, then the installed plugins (once)."""
    for name in OWNERS:
        importlib.import_module(name)
    _load_plugins()


@functools.cache
def _load_plugins():
    """Load every entry point of :data:`PLUGIN_GROUP` (3-9 ms to list them, measured)."""
    for ep in importlib.metadata.entry_points(group=PLUGIN_GROUP):
        try:
            ep.load()
        except Exception as exc:  # a plugin's own error: name it, in one line
            raise ConfigError(
                f"plugin {ep.name!r} ({PLUGIN_GROUP} entry point {ep.value!r}) failed to "
                f"load: {type(exc).__name__}: {exc}"
            ) from exc


class SelectorSection(Section):
    """A section where ``selector`` names an entry of ``registry``."""

    selector: ClassVar[str]
    registry: ClassVar[Registry]
    #: Every selector of the section and its registry (a section may have more than one,
    #: e.g. ``[satellite_array]``: ``active_beams`` and ``steering``); ``selector`` is the last.
    registries: ClassVar[dict[str, Registry]] = {}

    @property
    def chosen(self) -> str:
        """The name of the chosen entry."""
        return getattr(self, self.selector)

    @property
    def params(self) -> Params:
        """The chosen entry's validated parameters."""
        return getattr(self, self.chosen)

    def build(self, context: Any = None):
        """Build the chosen entry."""
        return self.registry.build(self.chosen, self.params, context)

    def build_kind(self, selector: str, context: Any = None):
        """Build the entry chosen by the key ``selector`` (a section with several)."""
        name = getattr(self, selector)
        return self.registries[selector].build(name, getattr(self, name), context)

    def unchosen(self) -> list[str]:
        """The per-entry tables of every selector's registry that are not chosen."""
        chosen = {getattr(self, key) for key in self.registries}
        return [n for reg in self.registries.values() for n in reg.names() if n not in chosen]


class OutputSection(Section):
    """One table per output sink."""

    registry: ClassVar[Registry]

    def enabled(self) -> list[tuple[str, Params]]:
        """``(name, params)`` of every enabled sink, in registration order."""
        return [(n, getattr(self, n)) for n in self.registry.names() if getattr(self, n).enabled]


def _tables(registry, reserved):
    fields = {}
    for name in registry.names():
        if name in reserved:
            raise ValueError(f"{registry.key} entry {name!r} clashes with a key of its section")
        cfg = registry[name].config
        fields[name] = (cfg, Field(default_factory=cfg, description=registry[name].doc))
    return fields


def selector_section(title, registry, selector, default, base=SelectorSection, doc=""):
    """A :class:`SelectorSection` model for ``registry`` (one table per entry)."""
    names = registry.names()
    if default not in names:
        raise ValueError(f"{registry.key}: default {default!r} is not registered")
    reserved = set(base.model_fields) | {selector}
    model = create_model(
        title,
        __base__=base,
        **{selector: (Literal[names], Field(default, description=doc))},  # type: ignore[valid-type]
        **_tables(registry, reserved),
    )
    model.selector, model.registry = selector, registry
    model.registries = {**base.registries, selector: registry}
    return model


def output_section(registry):
    """The ``[output]`` model: one table per sink of ``registry``."""
    model = create_model("OutputSection", __base__=OutputSection, **_tables(registry, set()))
    model.registry = registry
    return model


def _kind_of(value):
    if isinstance(value, dict):
        return value.get("kind", "static")
    return getattr(value, "kind", None)


@functools.cache
def _terminal_section(gen):
    del gen  # cache key only
    registry = REGISTRIES["terminal.kind"]
    return selector_section("TerminalSection", registry, "kind", "upa", doc="UT antenna")


def terminal_section():
    """The ``[terminal]`` model; a ``[[population]]`` may carry a table of the same shape."""
    return _terminal_section(generation())


@functools.cache
def _population_models(gen):
    del gen  # cache key only
    registry = REGISTRIES["population.kind"]
    terminal = terminal_section()
    models = []
    for name in registry.names():
        base = registry[name].config
        model = create_model(
            f"{name.title().replace('_', '')}Population",
            __base__=base,
            kind=(Literal[name], Field(name, description="motion model")),  # type: ignore[valid-type]
            terminal=(
                terminal | None,
                Field(
                    None,
                    description="this population's UT antenna, a table shaped as [terminal] "
                    "(none: the [terminal] section)",
                ),
            ),
            panel_tilt_deg=(
                float,
                Field(
                    0.0,
                    ge=0.0,
                    le=90.0,
                    description="tilt of the UT panels' normal from local up, towards the "
                    "panel x axis [deg] (0: lying flat)",
                ),
            ),
            panel_azimuth_deg=(
                Annotated[float, Field(ge=-360.0, le=360.0)] | Literal["motion"],
                Field(
                    90.0,
                    description="azimuth of the panel x axis from north, clockwise [deg] (90: "
                    "east, the default frame), or 'motion': along the UT's horizontal "
                    "velocity (vehicles; a UT standing still keeps 90)",
                ),
            ),
        )
        models.append(Annotated[model, Tag(name)])
    return tuple(models)


def population_union():
    """``[[population]]`` item type: a union of the mobility kinds tagged by ``kind``."""
    members = _population_models(generation())
    return Annotated[Union[members], Discriminator(_kind_of)]  # noqa: UP007
