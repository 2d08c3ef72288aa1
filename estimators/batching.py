"""Selecting streams (users) of a batch: the one parser of "indices or a (B,) boolean mask", and
the protocol by which a batch drops users mid-run.

``take_users(rows)`` keeps the users ``rows`` of a batch (distinct indices into it, in their new
order) and forgets the others: the batch becomes ``len(rows)`` users, and each kept user goes on
exactly as it would have in the whole batch. A runner whose episodes end at different steps
shrinks its batch with it instead of stepping finished users. :class:`TakesUsers` implements it
from the names of a class's per-user attributes; :func:`takes_users` says whether an object
(a plug-in stage, say) has it.
"""

from __future__ import annotations

import copy
import dataclasses
from types import SimpleNamespace
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["TakesUsers", "stream_rows", "take_rows", "take_rows_in_place", "takes_users"]


def stream_rows(
    which: ArrayLike | None, batch_size: int, name: str = "users", unique: bool = True
) -> NDArray[np.intp]:
    """Indices of the selected streams of a batch of ``batch_size``.

    Args:
        which: None (every stream), integer indices, or a (B,) boolean mask.
        batch_size: B.
        name: the argument's name, for error messages.
        unique: reject a repeated index.

    Raises:
        ValueError: a mask of the wrong shape, non-integer or out-of-range indices, repeats.
    """
    b = batch_size
    if which is None:
        return np.arange(b)
    u = np.asarray(which)
    if u.dtype == bool:
        if u.shape != (b,):
            raise ValueError(f"{name} as a boolean mask must have shape ({b},), got {u.shape}")
        return np.flatnonzero(u)
    if u.size == 0:
        return np.zeros(0, dtype=np.intp)
    if not np.issubdtype(u.dtype, np.integer):
        raise ValueError(f"{name} must be integer indices in [0, {b - 1}] or a (B,) mask, got {u}")
    u = u.astype(np.intp).ravel()
    if u.min() < 0 or u.max() >= b:
        raise ValueError(f"{name} must lie in [0, {b - 1}], got {u}")
    if unique and np.unique(u).size != u.size:
        raise ValueError(f"{name} must not repeat an index, got {u}")
    return u


def take_rows(value: Any, rows: NDArray[np.intp]) -> Any:
    """The users ``rows`` of a per-user ``value``: an array's rows (axis 0), a list's items, and
    the same of every value of a dataclass, dict, tuple or namespace (a copy; the original is
    left alone). None stays None, and so do the fields a dataclass names in its class attribute
    ``shared_fields`` (values common to every user, such as a batch's clock).

    Raises:
        TypeError: a value of any other kind (a scalar has no users to take).
    """
    if value is None:
        return None
    if isinstance(value, np.ndarray):
        return value[rows]
    if isinstance(value, list):
        return [value[i] for i in rows]
    if isinstance(value, tuple):
        taken = [take_rows(v, rows) for v in value]
        return type(value)(*taken) if hasattr(value, "_fields") else tuple(taken)
    if isinstance(value, dict):
        return {k: take_rows(v, rows) for k, v in value.items()}
    if isinstance(value, SimpleNamespace):
        return SimpleNamespace(**{k: take_rows(v, rows) for k, v in vars(value).items()})
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        new = copy.copy(value)
        shared = getattr(value, "shared_fields", ())
        for f in dataclasses.fields(value):
            if f.name in shared:
                continue
            object.__setattr__(new, f.name, take_rows(getattr(value, f.name), rows))
        return new
    raise TypeError(f"take_rows: a {type(value).__name__} has no rows of users to take")


def take_rows_in_place(value: NDArray, rows: NDArray[np.intp]) -> NDArray:
    """``value[rows]`` for a large array that nothing else refers to: only the rows that change
    place are moved, into the first ``len(rows)`` rows, and that prefix (a view of ``value``) is
    returned. Cheap where ``rows`` leaves most users in place (``rows[i] == i``)."""
    k = rows.size
    moved = np.flatnonzero(rows != np.arange(k))
    if moved.size:
        value[moved] = value[rows[moved]]  # the right side is a copy: overlaps are safe
    return value[:k]


def takes_users(obj: Any) -> bool:
    """Whether ``obj`` can drop users mid-run: it has a callable ``take_users`` and, where that
    comes from :class:`TakesUsers`, its own class declares its per-user attributes (a subclass
    that adds state of its own must say so) and every one of its parts can too."""
    if isinstance(obj, TakesUsers):
        return TakesUsers.declares(type(obj)) and all(takes_users(p) for p in obj.user_parts())
    return callable(getattr(obj, "take_users", None))


class TakesUsers:
    """``take_users`` from the names of a class's per-user attributes.

    A class lists its attributes that hold one row per user in :attr:`per_user_fields` (taken
    with :func:`take_rows`), those that hold parts of the batch which take users themselves in
    :attr:`per_user_parts` (None allowed), and the attribute holding its batch size, if any, in
    :attr:`batch_size_field`. A class whose per-user state needs more (record views to re-bind,
    say) extends :meth:`take_users`. A subclass does not inherit the protocol silently: it
    declares its own :attr:`per_user_fields` (the parent's, if it adds none), or
    :func:`takes_users` says no and :meth:`take_users` refuses.
    """

    per_user_fields: ClassVar[tuple[str, ...]] = ()
    per_user_parts: ClassVar[tuple[str, ...]] = ()
    batch_size_field: ClassVar[str | None] = None

    def take_users(self, rows: NDArray[np.intp]) -> None:
        """Keep the users ``rows`` (distinct indices into the batch, in their new order).

        Raises:
            TypeError: the object's class does not declare its per-user attributes, or one of its
                parts cannot drop users (:func:`takes_users`); nothing is changed.
        """
        if not TakesUsers.declares(type(self)):
            raise TypeError(
                f"{type(self).__name__} does not declare its per-user attributes "
                "(per_user_fields), so it cannot drop users"
            )
        unable = [type(p).__name__ for p in self.user_parts() if not takes_users(p)]
        if unable:
            raise TypeError(
                f"{type(self).__name__} cannot drop users: a part of it "
                f"({', '.join(unable)}) has no take_users"
            )
        rows = np.asarray(rows, dtype=np.intp)
        for name in self.per_user_fields:
            setattr(self, name, take_rows(getattr(self, name), rows))
        for part in self.user_parts():
            part.take_users(rows)
        if self.batch_size_field is not None:
            setattr(self, self.batch_size_field, int(rows.size))

    def user_parts(self) -> list[Any]:
        """The parts named in :attr:`per_user_parts` (those that are not None), each once."""
        parts: dict[int, Any] = {}
        for name in self.per_user_parts:
            part = getattr(self, name)
            if part is not None:
                parts.setdefault(id(part), part)
        return list(parts.values())

    @staticmethod
    def declares(cls: type) -> bool:
        """Whether class ``cls`` itself declares its per-user attributes (or its own
        ``take_users``)."""
        return any(k in vars(cls) for k in ("per_user_fields", "per_user_parts", "take_users"))
