"""The stage registry and the public lookup API.

``sbplan.registry.matcher("fourier")`` returns a ready instance of the matcher registered as
``fourier``; ``matcher_names()`` lists the installed names. The same pair exists for every kind:
``binarizer``, ``extractor``, ``approximator``, ``matcher``, ``mapper``, ``footprint``, ``planner``.

Plugins are found through the ``sbplan`` entry-point group, built-in ones included. A plugin that
fails to import is recorded in :func:`load_errors` (and shown by ``sbplan plugins``) and the others
still load.
"""

from __future__ import annotations

import importlib.metadata
import logging
import threading
from dataclasses import dataclass
from typing import Any

import pluggy

from . import hookspecs
from .contracts import CONTRACTS, KINDS, Stage
from .errors import PluginError, SbplanError, StageError, UnknownStageError

ENTRY_POINT_GROUP = "sbplan"
_log = logging.getLogger("sbplan.registry")


@dataclass(frozen=True)
class StageInfo:
    kind: str
    name: str
    cls: type[Stage]
    origin: str
    description: str


@dataclass(frozen=True)
class SymbolInfo:
    name: str
    polygon: Any
    origin: str
    description: str


@dataclass(frozen=True)
class LoadFailure:
    plugin: str
    origin: str
    error: str


class StageRegistry:
    """Stage classes keyed by ``(kind, name)``, and candidate symbols keyed by name."""

    def __init__(self) -> None:
        self._stages: dict[tuple[str, str], StageInfo] = {}
        self._aliases: dict[tuple[str, str], str] = {}  # (kind, alias) -> name
        self._symbols: dict[str, SymbolInfo] = {}
        self.failures: list[LoadFailure] = []
        self._origin = "sbplan"

    # -- registration -------------------------------------------------------------------------
    def add(self, cls: type[Stage], *, origin: str | None = None, replace: bool = False) -> type[Stage]:
        """Register a stage class; its kind comes from the contract it subclasses."""
        kind = next((k for k, base in CONTRACTS.items() if isinstance(cls, type) and issubclass(cls, base)), None)
        if kind is None:
            raise PluginError(f"{cls!r} does not subclass a stage contract of sbplan.contracts")
        if not cls.name or not isinstance(cls.name, str):
            raise PluginError(f"{kind} class {cls.__qualname__} has no name")
        key = (kind, cls.name)
        if key in self._stages and not replace and self._stages[key].cls is not cls:
            raise PluginError(f"{kind} {cls.name!r} is registered twice "
                              f"({self._stages[key].origin} and {origin or self._origin})")
        description = cls.description or (cls.__doc__ or "").strip().split("\n")[0]
        for alias in getattr(cls, "aliases", ()):
            taken = self._aliases.get((kind, alias))
            if (kind, alias) in self._stages or (taken is not None and taken != cls.name and not replace):
                raise PluginError(f"{kind} {cls.name!r}: alias {alias!r} is already a {kind}'s name")
        self._stages[key] = StageInfo(kind, cls.name, cls, origin or self._origin, description)
        for alias in getattr(cls, "aliases", ()):
            self._aliases[(kind, alias)] = cls.name
        return cls

    def remove(self, kind: str, name: str) -> None:
        self._stages.pop((kind, name), None)
        for key in [k for k, v in self._aliases.items() if k[0] == kind and v == name]:
            del self._aliases[key]

    def add_symbol(self, name: str, polygon: Any, *, description: str = "", origin: str | None = None,
                   replace: bool = False) -> None:
        if name in self._symbols and not replace:
            raise PluginError(f"symbol {name!r} is registered twice")
        self._symbols[name] = SymbolInfo(name, polygon, origin or self._origin, description)

    # -- lookup -------------------------------------------------------------------------------
    def names(self, kind: str) -> list[str]:
        _check_kind(kind)
        return sorted(n for k, n in self._stages if k == kind)

    def info(self, kind: str, name: str) -> StageInfo:
        _check_kind(kind)
        try:
            return self._stages[(kind, self._aliases.get((kind, name), name))]
        except (KeyError, TypeError):
            raise UnknownStageError(kind, name, self.names(kind),
                                    [f"{f.plugin} ({f.error})" for f in self.failures]) from None

    def get(self, kind: str, name: str) -> type[Stage]:
        return self.info(kind, name).cls

    def create(self, kind: str, name: str | Stage, **options: Any) -> Stage:
        """An instance of the named stage (an instance passed in is returned as it is)."""
        if isinstance(name, Stage):
            return name
        info = self.info(kind, name)
        try:
            stage = info.cls(**options)
        except TypeError as exc:
            raise PluginError(f"{kind} {name!r}: bad options ({exc})") from None
        except SbplanError:
            raise
        except Exception as exc:  # a plugin's constructor that fails: named, not a traceback
            raise StageError(kind, name, info.origin, f"cannot be made: {type(exc).__name__}: {exc}") from exc
        _log.debug("%s %s%s", kind, info.cls.name, f" {options}" if options else "")
        return stage

    def all(self) -> list[StageInfo]:
        order = {k: i for i, k in enumerate(KINDS)}
        return sorted(self._stages.values(), key=lambda s: (order[s.kind], s.name))

    def symbols(self) -> dict[str, SymbolInfo]:
        return dict(sorted(self._symbols.items()))


def _check_kind(kind: str) -> None:
    if kind not in KINDS:
        raise PluginError(f"unknown stage kind {kind!r}; kinds: {', '.join(KINDS)}")


class SbplanPluginManager(pluggy.PluginManager):
    """A pluggy plugin manager that also remembers which plugins failed to load and which
    distribution each entry point came from."""

    def __init__(self) -> None:
        super().__init__(hookspecs.PROJECT)
        self.sbplan_failures: list[LoadFailure] = []
        self.sbplan_origins: dict[str, str] = {}


def get_plugin_manager(*, load_entry_points: bool = True) -> SbplanPluginManager:
    """A new plugin manager with sbplan's hookspecs and, unless told not to, every installed
    plugin of the ``sbplan`` entry-point group. Import failures are kept in ``pm.sbplan_failures``.
    """
    pm = SbplanPluginManager()
    pm.add_hookspecs(hookspecs)
    if load_entry_points:
        for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
            origin = ep.dist.name if ep.dist is not None else ep.value
            if pm.get_plugin(ep.name) is not None:
                continue
            try:
                plugin = ep.load()
                pm.register(plugin, name=ep.name)
            except Exception as exc:  # a broken plugin must not take the others down
                pm.sbplan_failures.append(LoadFailure(ep.name, origin, f"{type(exc).__name__}: {exc}"))
                continue
            pm.sbplan_origins[ep.name] = origin
    pm.check_pending()
    return pm


def build_registry(pm: pluggy.PluginManager | None = None) -> StageRegistry:
    """Ask every registered plugin to fill a new registry."""
    pm = pm or get_plugin_manager()
    registry = StageRegistry()
    registry.failures.extend(getattr(pm, "sbplan_failures", []))
    origins = getattr(pm, "sbplan_origins", {})
    # Each implementation is called on its own so that one failing plugin is reported by name
    # and the registrations of the others survive.
    for hook in (pm.hook.sbplan_register_stages, pm.hook.sbplan_register_symbols):
        for impl in reversed(hook.get_hookimpls()):
            registry._origin = origins.get(impl.plugin_name, impl.plugin_name or "?")
            try:
                impl.function(registry=registry)
            except Exception as exc:
                registry.failures.append(
                    LoadFailure(impl.plugin_name, registry._origin, f"{type(exc).__name__}: {exc}"))
    registry._origin = "sbplan"
    # Logged, not warned: a broken plugin nobody asked for must not print on every command. Who
    # names one of its stages is told (UnknownStageError lists the failures); `sbplan plugins`
    # and `sbplan -v` show them.
    for failure in registry.failures:
        _log.warning("sbplan plugin %r (%s) failed to load: %s", failure.plugin, failure.origin, failure.error)
    return registry


_lock = threading.Lock()
_registry: StageRegistry | None = None


def registry() -> StageRegistry:
    """The process-wide registry, built on first use from the installed plugins."""
    global _registry
    with _lock:
        if _registry is None:
            _registry = build_registry()
        return _registry


def reset() -> None:
    """Forget the process-wide registry; the next lookup rebuilds it (tests use this)."""
    global _registry
    with _lock:
        _registry = None


def load_errors() -> list[LoadFailure]:
    return list(registry().failures)


def stages() -> list[StageInfo]:
    return registry().all()


def symbol_names() -> list[str]:
    return list(registry().symbols())


def _lookup_pair(kind: str):
    def create(name: str | Stage, **options: Any) -> Any:
        return registry().create(kind, name, **options)

    def names() -> list[str]:
        return registry().names(kind)

    create.__name__, names.__name__ = kind, f"{kind}_names"
    create.__doc__ = f"An instance of the {kind} registered under ``name``, with ``options``."
    names.__doc__ = f"The names of the installed {kind}s, sorted."
    return create, names


binarizer, binarizer_names = _lookup_pair("binarizer")
extractor, extractor_names = _lookup_pair("extractor")
approximator, approximator_names = _lookup_pair("approximator")
matcher, matcher_names = _lookup_pair("matcher")
mapper, mapper_names = _lookup_pair("mapper")
footprint, footprint_names = _lookup_pair("footprint")
planner, planner_names = _lookup_pair("planner")
