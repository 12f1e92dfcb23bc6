"""The registry of control modes: a protocol names a mode, :func:`make_mode` builds it.

A mode module registers a factory under its name with the :func:`register`
decorator (applied to a class or a function taking keyword settings). The
modules that register themselves are imported at the bottom of this file, one
line each, so that importing :mod:`autonomy.modes` is enough to see every mode;
a new mode adds its module to that line and nothing else here.

Modes from other packages (issue 23; docs/modes.md): an installed package registers a
factory under a name in the entry-point group :data:`ENTRY_POINT_GROUP`
(``asa_study.modes``), or a protocol names one as ``"package.module:factory"``; both are
loaded on first use by :func:`mode_factory`, and a broken one (it does not import, it is
not callable, it builds no mode) is a ``ValueError`` naming it.

Settings reach a mode as keyword arguments (from a protocol file, say);
:func:`settings_from` turns them into the mode's frozen settings dataclass and
refuses unknown names with a ``ValueError`` that lists the allowed ones.
"""

from __future__ import annotations

import dataclasses
import importlib
from collections.abc import Callable
from importlib.metadata import EntryPoint, entry_points
from typing import Any, TypeVar

from autonomy.types import Mode

ModeFactory = Callable[..., Mode]
F = TypeVar("F", bound=ModeFactory)
S = TypeVar("S")

# mode name -> factory(**settings) -> Mode
MODES: dict[str, ModeFactory] = {}
ENTRY_POINT_GROUP = "asa_study.modes"
_LOADED: dict[str, ModeFactory] = {}  # modes from other packages, loaded once


def register(name: str) -> Callable[[F], F]:
    """Decorator registering ``factory`` as the mode ``name``.

    Registering a second, different factory under a taken name is refused.
    """

    def decorator(factory: F) -> F:
        existing = MODES.get(name)
        if existing is not None and existing is not factory:
            raise ValueError(f"mode {name!r} is registered already (by {existing!r})")
        MODES[name] = factory
        return factory

    return decorator


def _plugins() -> dict[str, EntryPoint]:
    """The entry points of :data:`ENTRY_POINT_GROUP` by name (the first of a name wins)."""
    found: dict[str, EntryPoint] = {}
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        found.setdefault(ep.name, ep)
    return found


def available_modes() -> list[str]:
    """Names of the registered modes and of the installed packages' modes, sorted."""
    return sorted(set(MODES) | set(_plugins()))


def _import_reference(name: str) -> ModeFactory:
    """The factory that ``"package.module:factory"`` names."""
    module_name, _, attribute = name.partition(":")
    try:
        obj: Any = importlib.import_module(module_name)
        for part in attribute.split("."):
            obj = getattr(obj, part)
    except Exception as error:  # a third party's module: any failure is its, not ours
        raise ValueError(
            f"mode {name!r}: cannot load {attribute!r} from module {module_name!r} "
            f"({type(error).__name__}: {' '.join(str(error).split())})"
        ) from None
    return obj


def _load_entry_point(name: str, ep: EntryPoint) -> ModeFactory:
    try:
        return ep.load()
    except Exception as error:  # a third party's module: any failure is its, not ours
        where = f" (package {ep.dist.name})" if ep.dist is not None else ""
        raise ValueError(
            f"mode {name!r}: entry point {ep.name} = {ep.value!r} of group "
            f"{ENTRY_POINT_GROUP}{where} cannot be loaded "
            f"({type(error).__name__}: {' '.join(str(error).split())})"
        ) from None


def mode_factory(name: str) -> ModeFactory:
    """The factory of mode ``name``: registered here, an entry point of
    :data:`ENTRY_POINT_GROUP`, or ``"package.module:factory"``.

    Raises
    ------
    ValueError
        An unknown name (listing the known ones), or a mode from another package that
        cannot be loaded or is not callable (naming it and why).
    """
    factory = MODES.get(name) or _LOADED.get(name)
    if factory is not None:
        return factory
    if ":" in name:
        factory = _import_reference(name)
    else:
        ep = _plugins().get(name)
        if ep is None:
            raise ValueError(
                f"unknown mode {name!r}; registered modes: {', '.join(available_modes())} "
                f"(or 'package.module:factory', docs/modes.md)"
            )
        factory = _load_entry_point(name, ep)
    if not callable(factory):
        raise ValueError(f"mode {name!r}: {factory!r} is not callable (a mode factory is)")
    _LOADED[name] = factory
    return factory


def make_mode(name: str, **settings: Any) -> Mode:
    """Build the mode ``name`` (:func:`mode_factory`) with the given settings.

    Raises
    ------
    ValueError
        For an unknown name (listing the registered ones), unknown settings, or a mode
        from another package that fails to build or lacks ``reset`` and ``step``.
    """
    factory = mode_factory(name)
    if name in MODES:
        return with_defaults(factory(**settings))
    try:
        mode = factory(**settings)
    except ValueError:
        raise
    except Exception as error:  # a third party's factory: any failure is its, not ours
        raise ValueError(
            f"mode {name!r}: its factory failed ({type(error).__name__}: "
            f"{' '.join(str(error).split())})"
        ) from None
    missing = [m for m in ("reset", "step") if not callable(getattr(mode, m, None))]
    if missing:
        raise ValueError(
            f"mode {name!r}: its factory returned a {type(mode).__name__}, which has no "
            f"{' and no '.join(f'{m}()' for m in missing)} (the mode interface: docs/modes.md)"
        )
    return with_defaults(mode)


def with_defaults(mode: Any) -> Mode:
    """``mode`` with every hook :class:`autonomy.types.Mode` declares: ``mode`` itself if it
    has them all, else a view of it that adds the defaults of the missing ones (a mode
    class that does not subclass ``Mode``, e.g. one from another package)."""
    return mode if isinstance(mode, Mode) else _WithDefaults(mode)


# the optional hooks of :class:`Mode` (those with a default)
_HOOKS = ("label_tasks", "settings_dict", "needs_intention", "observe_intention")


class _WithDefaults(Mode):
    """A mode with :class:`Mode`'s defaults for the hooks it lacks; its own members
    (``name``, ``settings``, its own hooks, ...) pass through. For a mode without
    ``settings_dict`` whose ``settings`` is a dataclass, ``settings_dict`` gives
    ``dataclasses.asdict`` of it (a mode from another package written before the hook)."""

    def __init__(self, mode: Any) -> None:
        self.mode = mode
        # its bound methods, so that a tick calls them without an extra call
        self.reset = mode.reset
        self.step = mode.step
        for hook in _HOOKS:  # the class's defaults would shadow the mode's own
            if hasattr(mode, hook):
                setattr(self, hook, getattr(mode, hook))

    def settings_dict(self) -> dict[str, Any]:
        settings = getattr(self.mode, "settings", None)  # the adapter's one probe
        if dataclasses.is_dataclass(settings) and not isinstance(settings, type):
            return dataclasses.asdict(settings)
        return {}

    def __getattr__(self, attr: str) -> Any:
        if attr == "mode":  # not set yet
            raise AttributeError(attr)
        return getattr(self.mode, attr)


def settings_from(cls: type[S], values: dict[str, Any], *, where: str) -> S:
    """Build the settings dataclass ``cls`` from keyword ``values``.

    A field whose default is itself a settings dataclass accepts a dict of its
    fields (one level per nesting). ``where`` names the owner in error messages,
    e.g. ``"mode 'reactive_bn'"``.
    """
    defaults = cls()
    allowed = [f.name for f in dataclasses.fields(cls)]
    unknown = sorted(set(values) - set(allowed))
    if unknown:
        raise ValueError(f"{where}: unknown setting {unknown[0]!r}; allowed: {', '.join(allowed)}")
    converted = {}
    for key, value in values.items():
        default = getattr(defaults, key)
        if dataclasses.is_dataclass(default) and isinstance(value, dict):
            value = settings_from(type(default), value, where=f"{where}, setting {key!r}")
        converted[key] = value
    return dataclasses.replace(defaults, **converted)


# Modes that register themselves on import; add a new mode's module here.
from autonomy import manual, reactive_bn  # noqa: E402, F401, I001
from autonomy import contextual  # noqa: E402, F401, I001
