"""Named collections, and the loader of ``"package.module:attr"`` plug-ins.

* :func:`load_attr` — the object a ``"package.module:attr"`` or ``"path/to/file.py:attr"`` string
  names (the file imported once, as a module of its own), with a clear :class:`StageError` for a
  bad string, a module that does not import or a missing attribute.
* :class:`Registry` — every named collection of the project (tasks, techniques, populations,
  conditions, scripted policies, sensor presets, stages): name -> entry with a one-line
  description, entries given as objects or as ``"module:attr"`` strings imported on first use,
  one lookup (:meth:`Registry.get`) with one error format (``<what>=<name!r>: unknown; valid
  names: a, b, c``), deprecated names (:meth:`Registry.rename`), and the mapping protocol.
* :class:`StageRegistry` — the named implementations of one estimation stage: a
  :class:`Registry` of factories that also accepts a plug-in's own ``"module:attr"``, a class or
  factory, or an object with a ``build`` method, and builds it checked against a protocol
  (:func:`check_members`).
* :func:`protocol_members` — the public members a :class:`typing.Protocol` declares, read from the
  classes themselves (on every Python that has protocols).
* :func:`renamed_attributes` — a module ``__getattr__`` keeping old attribute names importable.

The stage protocols, their contracts and the five stage registries are in
:mod:`estimators.stages`.
"""

from __future__ import annotations

import importlib
import inspect
import warnings
from collections.abc import Callable, Iterator, Mapping, MutableMapping
from types import MappingProxyType
from typing import Any, Generic, Protocol, TypeVar

from estimators.validation import value_repr

__all__ = [
    "Registry",
    "StageError",
    "StageRegistry",
    "call_text",
    "check_members",
    "is_method",
    "load_attr",
    "protocol_member",
    "protocol_members",
    "renamed_attributes",
]


class StageError(ValueError):
    """A stage's plug-in could not be built, raised, or returned what the stage does not allow."""


def protocol_members(protocol: type) -> list[str]:
    """The public members a protocol class declares, in declaration order: its annotated
    attributes and the methods and properties of its class body (and of its protocol bases).

    Read from the classes' own ``__annotations__`` and ``__dict__``, so it works on every
    Python that has :class:`typing.Protocol` (3.12's ``__protocol_attrs__`` is not needed)."""
    names: dict[str, None] = {}
    for base in reversed(protocol.__mro__):
        if base in (object, Protocol, Generic) or not base.__dict__.get("_is_protocol", False):
            continue
        for name in (*inspect.get_annotations(base), *vars(base)):
            if not name.startswith("_"):
                names[name] = None
    return list(names)


def protocol_member(protocol: type, name: str) -> Any:
    """The object the protocol's class body binds to ``name`` (None: annotated only)."""
    for base in protocol.__mro__:
        if name in vars(base):
            return vars(base)[name]
    return None


def is_method(obj: Any) -> bool:
    """Whether a protocol member is a method (callable, not a class)."""
    return callable(obj) and not isinstance(obj, type)


def call_text(method: str, call: tuple[tuple[str, ...], tuple[str, ...]]) -> str:
    """The call ``method(a, b, c=...)`` that ``call`` (positional names, keyword names) makes."""
    positional, keywords = call
    return f"{method}({', '.join((*positional, *(f'{k}=...' for k in keywords)))})"


def check_members(stage: Any, protocol: type, contract: Any) -> list[str]:
    """What ``stage`` lacks of ``protocol`` and its contract, one phrase each (empty: nothing):
    the members it does not have, by name, the methods that are not callable, and those whose
    signature does not accept the environment's call (``contract.calls``: method ->
    (positional argument names, keyword argument names))."""
    problems: list[str] = []
    missing = [name for name in protocol_members(protocol) if not hasattr(stage, name)]
    if missing:
        problems.append(f"lacks {', '.join(missing)} of the {protocol.__name__} protocol")
    for name in protocol_members(protocol):
        if name in missing or not is_method(protocol_member(protocol, name)):
            continue
        method = getattr(stage, name)
        if not callable(method):
            problems.append(f"has a {type(method).__name__} {name!r} where a method is needed")
            continue
        if name not in contract.calls:
            continue
        positional, keywords = contract.calls[name]
        try:
            signature = inspect.signature(method)
        except (TypeError, ValueError):  # a builtin without a signature: let the call tell
            continue
        try:
            signature.bind(*positional, **dict.fromkeys(keywords))
        except TypeError as err:
            problems.append(
                f"has {name}{signature}, which cannot be called as "
                f"{call_text(name, contract.calls[name])} ({err})"
            )
    return problems


def load_attr(spec: str, what: str) -> Any:
    """The object a ``"package.module:attr"`` string names, or ``"path/to/file.py:attr"`` (the
    file is imported as a module of its own), with clear errors for bad strings."""
    module_name, _, attr = spec.rpartition(":")
    if not module_name or not attr:
        raise StageError(
            f"{what}={spec!r}: a plug-in is named 'package.module:attr' or 'path/file.py:attr'"
        )
    if module_name.endswith(".py"):
        module = _import_file(module_name, spec, what)
    else:
        try:
            module = importlib.import_module(module_name)
        except ImportError as err:
            raise StageError(f"{what}={spec!r}: cannot import {module_name!r} ({err})") from None
    obj: Any = module
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise StageError(f"{what}={spec!r}: {module_name!r} has no attribute {attr!r}")
        obj = getattr(obj, part)
    return obj


def _import_file(path_text: str, spec: str, what: str) -> Any:
    """Import a Python file once per process, under a name derived from its resolved path."""
    import hashlib
    import importlib.util
    import sys
    from pathlib import Path

    path = Path(path_text).expanduser().resolve()
    if not path.is_file():
        raise StageError(f"{what}={spec!r}: no such file {str(path)!r}")
    digest = hashlib.sha1(str(path).encode()).hexdigest()[:10]
    name = f"vrloco_plugin_{path.stem}_{digest}"
    if name in sys.modules:
        return sys.modules[name]
    loader_spec = importlib.util.spec_from_file_location(name, path)
    if loader_spec is None or loader_spec.loader is None:
        raise StageError(f"{what}={spec!r}: cannot import {str(path)!r}")
    module = importlib.util.module_from_spec(loader_spec)
    sys.modules[name] = module
    try:
        loader_spec.loader.exec_module(module)
    except Exception as err:
        del sys.modules[name]
        raise StageError(f"{what}={spec!r}: importing {str(path)!r} failed: {err}") from err
    return module


T = TypeVar("T")

#: ``get``'s default when none is given: an unknown name raises.
_RAISE: Any = object()


class _Entry:
    """One registered entry: the object, or the ``"module:attr"`` naming it until first use."""

    __slots__ = ("description", "loaded", "target")

    def __init__(self, target: Any, description: str | None, loaded: bool) -> None:
        self.target = target
        self.description = description
        self.loaded = loaded


class Registry(MutableMapping[str, T]):
    """A named collection: name -> entry, each with a one-line description.

    An entry is given as the object itself or as a ``"package.module:attr"`` (or
    ``"path/to/file.py:attr"``) string naming it, imported on first use (:func:`load_attr`) and
    kept from then on. Looking a name up (:meth:`get`) raises one error format,
    ``<what>=<name!r>: unknown; valid names: a, b, c``; a name that was renamed (:meth:`rename`)
    still resolves, with a :class:`DeprecationWarning`.

    It is a mutable mapping of the current names to their (imported) entries:
    ``registry[name]``, ``name in registry``, ``for name in registry``, ``len``, ``items()``,
    ``values()``, ``keys()``, ``registry[name] = entry``, ``del registry[name]``, ``update``,
    ``clear`` and ``==`` against a dict work as on a dict. Deprecated names are ``in`` it and can
    be looked up, but no listing (iteration, :meth:`names`, :meth:`describe`) shows them.

    Args:
        what: what an entry is, for messages (``"technique"``); also the name an unknown name is
            given as in the error (``technique='x': unknown; ...``).
        kind: the type (or types) of an entry: :meth:`get` returns an instance of it unchanged,
            and registering an object of another type is a TypeError. None: any object.
        load: called as ``load(obj, name, target)`` on an object a ``"module:attr"`` string
            named (a lazily registered entry when first used, or a plug-in :meth:`get` was
            given); returns the entry, or raises saying why ``obj`` is not one. None: the
            object as it is.
        plugins: :meth:`get` also accepts an unregistered ``"module:attr"`` string, imported
            and passed through ``load`` (not registered).
        also: what else :meth:`get` accepts, appended to the error's list of valid names
            (``"a Population"`` gives ``valid names: idealised, human, or a Population``).
    """

    #: The exception :meth:`get` raises for an unknown name.
    error: type[ValueError] = ValueError

    def __init__(
        self,
        what: str,
        *,
        kind: type | tuple[type, ...] | None = None,
        load: Callable[[Any, str, str], T] | None = None,
        plugins: bool = False,
        also: str = "",
    ) -> None:
        self.what = what
        self.kind = kind
        self.plugins = plugins
        self.also = also
        self._load_hook = load
        self._entries: dict[str, _Entry] = {}
        self._renamed: dict[str, str] = {}

    # ------------------------------------------------------------------ registering

    def register(self, name: str, entry: T | str, description: str | None = None) -> T | str:
        """Add ``name`` -> ``entry`` (the object, or ``"module:attr"`` naming it, imported on
        first use), with a one-line description (None: the entry's own ``description``
        attribute, read when first listed for a ``"module:attr"`` entry). Registering a name
        again replaces it. Returns ``entry``."""
        if not isinstance(name, str) or not name:
            raise ValueError(f"{self.what} name {name!r}: must be a non-empty string")
        lazy = isinstance(entry, str)
        if lazy and ":" not in entry:
            raise ValueError(
                f"{self.what} {name!r}: a string entry is 'package.module:attr' or "
                f"'path/file.py:attr', got {entry!r}"
            )
        if not lazy and self.kind is not None and not isinstance(entry, self.kind):
            raise TypeError(
                f"{self.what} {name!r}: an entry must be {_kind_text(self.kind)} or "
                f"'module:attr', got {type(entry).__name__}"
            )
        if description is None and not lazy:
            text = getattr(entry, "description", None)
            description = text if isinstance(text, str) else ""
        self._entries[name] = _Entry(entry, description, loaded=not lazy)
        return entry

    def rename(self, old: str, new: str) -> None:
        """Keep ``old`` working as a deprecated name of the registered ``new``: it resolves to
        ``new`` with a :class:`DeprecationWarning`, and no listing shows it."""
        if new not in self._entries:
            raise ValueError(f"{self.what}: cannot rename {old!r} to unregistered {new!r}")
        self._renamed[old] = new

    @property
    def renamed(self) -> Mapping[str, str]:
        """Deprecated name -> current name (read-only, live)."""
        return MappingProxyType(self._renamed)

    def canonical(self, spec: Any, *, stacklevel: int = 3) -> Any:
        """``spec`` with a deprecated name replaced by its current one (warning once per call
        site; ``stacklevel`` as :func:`warnings.warn` counts it from here, the default naming
        the caller of the function that called this); anything else unchanged."""
        if isinstance(spec, str) and spec in self._renamed:
            new = self._renamed[spec]
            warnings.warn(
                f"{self.what} {spec!r} is now called {new!r}; the old name will be removed "
                "in the next release",
                DeprecationWarning,
                stacklevel=stacklevel,
            )
            return new
        return spec

    # ------------------------------------------------------------------ looking up

    def get(  # type: ignore[override]
        self, name: Any, default: Any = _RAISE, *, field: str | None = None, stacklevel: int = 3
    ) -> Any:
        """The entry ``name`` names: a registered name (a deprecated one with a warning), an
        instance of ``kind`` (returned as it is) or, with ``plugins``, a ``"module:attr"``
        string.

        Unlike ``dict.get``, an unknown name raises (:meth:`unknown`, naming ``field``, default
        ``what``) unless a ``default`` is given, which is then returned instead.
        ``stacklevel`` is the deprecation warning's, counted from this method (the default
        names the caller of the function that called it)."""
        if self.kind is not None and isinstance(name, self.kind):
            return name
        name = self.canonical(name, stacklevel=stacklevel + 1)
        if isinstance(name, str):
            if name in self._entries:
                return self._get(name)
            if self.plugins and ":" in name:
                return self._loaded(load_attr(name, self.what), name, name)
        if default is not _RAISE:
            return default
        raise self.unknown(name, field=field)

    def unknown(self, name: Any, *, field: str | None = None, also: str | None = None) -> Exception:
        """The error for an unknown ``name`` (to raise):
        ``<field>=<name!r>: unknown; valid names: a, b, c[, or <also>]``."""
        also = self.also if also is None else also
        shown = repr(name) if isinstance(name, str) else value_repr(name)
        names = ", ".join(self.names())
        return self.error(
            f"{field or self.what}={shown}: unknown; valid names: {names}"
            + (f", or {also}" if also else "")
        )

    def names(self) -> list[str]:
        """The registered names, in registration order (deprecated names not included)."""
        return list(self._entries)

    def describe(self) -> dict[str, str]:
        """name -> one-line description (an entry registered as ``"module:attr"`` without one
        is imported to read its ``description``)."""
        out = {}
        for name, entry in self._entries.items():
            if entry.description is None:
                text = getattr(self._get(name), "description", None)
                entry.description = text if isinstance(text, str) else ""
            out[name] = entry.description
        return out

    def _get(self, name: str) -> Any:
        """The entry registered as ``name``, imported (once) if it was given as a string."""
        entry = self._entries[name]
        if not entry.loaded:
            entry.target = self._loaded(load_attr(entry.target, self.what), name, entry.target)
            entry.loaded = True
        return entry.target

    def _loaded(self, obj: Any, name: str, target: str) -> Any:
        return obj if self._load_hook is None else self._load_hook(obj, name, target)

    # ------------------------------------------------------------------ the mapping protocol

    def __getitem__(self, name: str) -> T:
        name = self.canonical(name)
        if not isinstance(name, str) or name not in self._entries:
            raise KeyError(name)
        return self._get(name)

    def __setitem__(self, name: str, entry: T) -> None:
        self.register(name, entry)

    def __delitem__(self, name: str) -> None:
        del self._entries[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._entries)

    def __len__(self) -> int:
        return len(self._entries)

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and (name in self._entries or name in self._renamed)

    def pop(self, name: str, *default: Any) -> Any:
        """Remove ``name`` and return its entry as registered (a ``"module:attr"`` entry never
        used: that string, not imported), or ``default`` if given and ``name`` is not
        registered."""
        if name in self._entries:
            return self._entries.pop(name).target
        if default:
            return default[0]
        raise KeyError(name)

    def clear(self) -> None:
        """Remove every entry (deprecated names stay, resolving to nothing until their new
        names are registered again)."""
        self._entries.clear()

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.what!r}: {', '.join(self._entries)}>"


def _kind_text(kind: type | tuple[type, ...]) -> str:
    kinds = kind if isinstance(kind, tuple) else (kind,)
    return " or ".join(f"a {k.__name__}" for k in kinds)


class StageRegistry(Registry[Callable[..., Any]]):
    """Named implementations of one stage: a :class:`Registry` of factories given as
    ``"module:attr"`` (imported on first use) that also builds a stage, from a name, a plug-in's
    own ``"module:attr"``, a class or factory, or an object with a ``build`` method, checked
    against a protocol (:func:`check_members`).

    Args:
        stage: the stage's name, for error messages (``"attitude"``).
        protocol: the protocol every built stage must satisfy.
        signature: how factories are called, for the docs and error messages.
        contract: how the environment calls the stage and what it must return (a
            :class:`estimators.stages.StageContract`; :meth:`build` reads its ``calls``).
        home: ``"module:attr"`` of the variable that holds this registry, by which a pickle
            names it (its contract holds functions that cannot be pickled); None: not picklable.
    """

    error = StageError

    def __init__(
        self,
        stage: str,
        protocol: type,
        signature: str,
        contract: Any,
        *,
        home: str | None = None,
    ) -> None:
        super().__init__(
            stage, also="'package.module:attr' (or 'path/file.py:attr') naming your own"
        )
        self.stage = stage
        self.protocol = protocol
        self.signature = signature
        self.contract = contract
        self.home = home

    def register(  # type: ignore[override]
        self, name: str, target: str, description: str
    ) -> str:
        """Add ``name`` -> the factory at ``target`` ("module:attr"), with a one-line
        description. Re-registering a name replaces it."""
        if not isinstance(target, str) or ":" not in target:
            raise ValueError(f"target {target!r} must be 'package.module:attr'")
        return super().register(name, target, description)

    def __setitem__(self, name: str, target: Any) -> None:
        self.register(name, target, "")

    def __reduce__(self) -> tuple[Any, ...]:
        """Pickled by name: the variable :attr:`home` names (its contract holds lambdas)."""
        if self.home is None:
            raise TypeError(
                f"the {self.stage} registry has no home ('module:attr') to be pickled by"
            )
        return (load_attr, (self.home, self.stage))

    def check(self, spec: Any) -> None:
        """Raise a clear :class:`StageError` if ``spec`` names nothing buildable (without
        building it). Registered names pass (their modules are imported when first built);
        "module:attr" strings are imported and resolved; other objects must be callable or
        have a ``build`` method."""
        if not (isinstance(spec, str) and spec in self._entries):
            self.factory(spec)

    def label(self, spec: Any) -> str:
        """A short name of ``spec`` for tables and errors."""
        if isinstance(spec, str):
            return spec
        name = getattr(spec, "name", None)
        if isinstance(name, str):
            return name
        return type(spec).__name__ if not callable(spec) else getattr(spec, "__name__", "custom")

    def factory(self, spec: Any) -> Callable[..., Any]:
        """The callable that builds ``spec``'s stage.

        ``spec`` is a registered name, a ``"module:attr"`` string naming a class or factory, an
        object with a ``build(...)`` method (a parameter dataclass such as
        :class:`estimators.attitude.AttitudeParams`), or a class / factory.
        """
        spec = self.canonical(spec)
        if isinstance(spec, str):
            if spec in self._entries:
                return self._get(spec)
            if ":" in spec:
                return _as_factory(load_attr(spec, self.stage), self.stage, spec)
            raise self.unknown(spec)
        return _as_factory(spec, self.stage, type(spec).__name__)

    def build(self, spec: Any, *args: Any, **kwargs: Any) -> Any:
        """Build ``spec``'s stage with the stage's factory arguments and check that it has every
        member of the protocol and that its methods accept the environment's calls
        (:func:`check_members`)."""
        factory = self.factory(spec)
        label = self.label(spec)
        try:
            stage = factory(*args, **kwargs)
        except StageError:
            raise
        except Exception as err:  # a user's factory failing: say which stage and plug-in
            raise StageError(
                f"{self.stage} plug-in {label!r} failed to build with {self.signature}: "
                f"{type(err).__name__}: {err}"
            ) from err
        problems = check_members(stage, self.protocol, self.contract)
        if problems:
            raise StageError(
                f"{self.stage} plug-in {label!r} built a {type(stage).__name__}, which "
                f"{'; and '.join(problems)} (docs/protocols.md)"
            )
        return stage


def _as_factory(obj: Any, stage: str, label: str) -> Callable[..., Any]:
    build = getattr(obj, "build", None)
    if callable(build) and not isinstance(obj, type):
        return build
    if callable(obj):
        return obj
    raise StageError(
        f"{stage}={label!r}: a plug-in must be a registered name, 'package.module:attr', a class "
        "or factory, or an object with a build() method"
    )


def renamed_attributes(module_globals: dict[str, Any], renamed: dict[str, str]) -> Any:
    """A module ``__getattr__`` that keeps each old name in ``renamed`` importable as the object
    now called by its new name, with a :class:`DeprecationWarning`; other names are an
    :class:`AttributeError` as usual."""
    module = module_globals["__name__"]

    def __getattr__(name: str) -> Any:
        if name in renamed:
            new = renamed[name]
            warnings.warn(
                f"{module}.{name} is now called {new}; the old name will be removed in the "
                "next release",
                DeprecationWarning,
                stacklevel=2,
            )
            return module_globals[new]
        raise AttributeError(f"module {module!r} has no attribute {name!r}")

    return __getattr__
