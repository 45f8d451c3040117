"""One registry per pluggable kind: a name, a parameter model and a builder per entry.

A pluggable kind (terminal antenna, atmosphere model, controller policy, mobility model,
beam selector, scheduler, precoder, steering mode, output sink) declares a
``typing.Protocol`` and one :class:`Registry`. An entry registers under a config name
with its own pydantic parameter model (a :class:`Params` subclass); the config loader
builds its schema from the registries, so a new kind is validated, documented
(``docs/config.md``) and checked by ``leolink validate`` without further edits::

    class FlatConfig(Params):
        gain_db: float = Field(0.0, description="gain in every direction [dB]")

    @TERMINALS.register("flat", config=FlatConfig)
    class Flat:
        \"\"\"The same gain in every direction.\"\"\"
        def __init__(self, gain_db): ...

An entry is built from its validated parameters with ``registry.build(name, params,
context)``: by default ``factory(**params)``; an entry that needs more of the scenario
than its own table (the carrier frequency, the site, the run's random generator) gives
``build=lambda params, context: ...``.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Callable, Iterator
from typing import Any, Generic, TypeVar

from pydantic import BaseModel, ConfigDict

from leolink.errors import ConfigError

__all__ = ["REGISTRIES", "STRICT_MODEL", "Entry", "Params", "Registry", "generation"]

T = TypeVar("T")

#: Every registry by its config key (``"terminal.kind"``), in creation order.
REGISTRIES: dict[str, Registry[Any]] = {}
_generation = itertools.count(1)
_current = 0


def generation() -> int:
    """A number that changes whenever an entry is registered (config schema cache key)."""
    return _current


#: The pydantic settings of every config table and parameter model: unknown keys, NaN/inf
#: and type coercions refused; validators built when the class is made (pydantic's default).
#: The deferred build (``defer_build``, behind an environment variable) is not thread-safe
#: and earned nothing measurable: a 10-epoch paper run 2.55 s deferred, 3.02 s not (medians
#: of 3, spread 1.0-3.4 s on a loaded machine; see also leolink.app.process).
STRICT_MODEL = ConfigDict(
    extra="forbid",
    frozen=True,
    validate_default=True,
    allow_inf_nan=False,
    strict=True,
)


class Params(BaseModel):
    """Base of every entry's parameter model: unknown keys, NaN/inf and coercions refused."""

    model_config = STRICT_MODEL


class NoParams(Params):
    """An entry without parameters."""


@dataclasses.dataclass(frozen=True)
class Entry(Generic[T]):
    """One registered kind."""

    name: str
    factory: Callable[..., T] | None
    config: type[Params]
    build: Callable[[Any, Any], T] | None
    doc: str

    def make(self, params: Params | None = None, context: Any = None) -> T:
        """Build the entry from validated ``params`` (defaults if None)."""
        params = self.config() if params is None else params
        if self.build is not None:
            return self.build(params, context)
        assert self.factory is not None  # add() always gives a build function
        return self.factory(**dict(params))


class Registry(Generic[T]):
    """Entries of one pluggable kind, keyed by their config name.

    Parameters
    ----------
    key : str
        Config key that selects an entry, e.g. ``"terminal.kind"``.
    protocol : type, optional
        A ``runtime_checkable`` Protocol every built object must satisfy.
    """

    def __init__(self, key: str, protocol: type | None = None):
        if key in REGISTRIES:
            raise ValueError(f"a registry for {key!r} exists already")
        self.key, self.protocol = key, protocol
        self._entries: dict[str, Entry[T]] = {}
        REGISTRIES[key] = self

    def register(
        self,
        name: str,
        *,
        config: type[Params] = NoParams,
        build: Callable[[Any, Any], T] | None = None,
        replace: bool = False,
    ) -> Callable[[Callable[..., T]], Callable[..., T]]:
        """Decorator registering a class or factory function under ``name``."""
        self._check(name, config)

        def decorate(factory: Callable[..., T]) -> Callable[..., T]:
            doc = (factory.__doc__ or "").strip().splitlines()
            self._add(Entry(name, factory, config, build, doc[0] if doc else ""), replace)
            return factory

        return decorate

    def add(
        self,
        name: str,
        build: Callable[[Any, Any], T],
        *,
        doc: str,
        config: type[Params] = NoParams,
        replace: bool = False,
    ) -> None:
        """Register a builder function ``build(params, context)`` under ``name``."""
        self._check(name, config)
        self._add(Entry(name, None, config, build, doc), replace)

    def remove(self, name: str) -> None:
        """Unregister ``name`` (tests that register a kind of their own clean up with it)."""
        global _current
        del self._entries[name]
        _current = next(_generation)

    def _check(self, name: str, config: type[Params]) -> None:
        if not name.isidentifier():
            raise ValueError(f"{self.key}: {name!r} is not a valid name (letters, digits, _)")
        if not (isinstance(config, type) and issubclass(config, Params)):
            raise TypeError(f"{self.key} {name!r}: config must be a leolink.registry.Params")

    def _add(self, entry: Entry[T], replace: bool) -> None:
        global _current
        if entry.name in self._entries and not replace:
            raise ValueError(f"{self.key} {entry.name!r} is registered already")
        self._entries[entry.name] = entry
        _current = next(_generation)

    def __contains__(self, name: object) -> bool:
        return name in self._entries

    def __iter__(self) -> Iterator[str]:
        return iter(self._entries)

    def __len__(self) -> int:
        return len(self._entries)

    def names(self) -> tuple[str, ...]:
        """Registered names, in registration order."""
        return tuple(self._entries)

    def __getitem__(self, name: str) -> Entry[T]:
        try:
            return self._entries[name]
        except KeyError:
            allowed = ", ".join(repr(n) for n in self._entries)
            raise ConfigError(
                f"{self.key} = {name!r} is not allowed; use one of {allowed}"
            ) from None

    def build(self, name: str, params: Params | None = None, context: Any = None) -> T:
        """Build entry ``name``; checks the result against the protocol."""
        obj = self[name].make(params, context)
        if self.protocol is not None and not isinstance(obj, self.protocol):
            raise TypeError(
                f"{self.key} {name!r} built a {type(obj).__name__}, which does not follow "
                f"the {self.protocol.__name__} protocol"
            )
        return obj

    def __repr__(self) -> str:
        return f"Registry({self.key!r}, {list(self._entries)})"
