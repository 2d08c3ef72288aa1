"""The proxy that holds a plug-in stage to its contract.

:class:`CheckedStage` wraps a plug-in that is not one of the package's own stages
(:func:`vrloco_env.pipeline.build_stages` does it once) and checks every output of ``update``
against the stage's :class:`~estimators.stages.StageContract`: a wrong shape, a NaN, a zero
quaternion, a step time from the future or a position 1e9 m away gets a
:class:`~estimators.registry.StageError` naming the stage, the plug-in, the first offending user
and sample, its value and the rule.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.batching import stream_rows, takes_users
from estimators.registry import Registry, StageError
from estimators.stages import MalformedOutput, Output, Rule, StageContract

__all__ = ["CheckedStage"]


def _format_value(value: NDArray[np.float64]) -> str:
    """A number or a short vector, 6 significant digits each."""
    if np.ndim(value) == 0:
        return f"{float(value):.6g}"
    return "[" + ", ".join(f"{float(v):.6g}" for v in np.ravel(value)) + "]"


class CheckedStage:
    """A plug-in stage behind its stage's :class:`StageContract`.

    ``update`` calls the plug-in's and checks the result: its structure, the shape of each
    :class:`Output` and then every :class:`Rule`, in order; the environment receives the checked
    arrays (as float64, ``int8`` step states and counts, a boolean hand validity; a step stage's
    result as an :class:`estimators.stages.GaitChunk`). ``reset`` forwards to the plug-in's. An
    exception inside either, or a result the contract does not allow, is a :class:`StageError`
    naming the stage and the plug-in (and, for a broken rule, the first offending user and
    sample, its value and the rule). Every other attribute is the plug-in's: ``take_users``
    exists exactly where the plug-in can drop users (:func:`estimators.batching.takes_users`),
    and ``report_delay_s``, ``uses_torso`` or ``heading`` read through.

    The proxy keeps one number per user: the samples its stream has seen since its last reset
    (the clock that step times are checked on), which ``reset`` and ``take_users`` follow.

    Args:
        stage: the built plug-in.
        registry: its stage's registry (name and contract).
        label: the plug-in's short name, for errors.
        batch_size: B.
        rate_hz: the stage's sample rate (Hz) for the stages built with one.
    """

    def __init__(
        self,
        stage: Any,
        registry: Registry,
        label: str,
        batch_size: int,
        rate_hz: float | None = None,
    ) -> None:
        self._stage = stage
        self._registry = registry
        self._name = registry.stage
        self._label = label
        self._rate_hz = rate_hz
        self._clock = np.zeros(batch_size, np.int64)

    @property
    def wrapped(self) -> Any:
        """The plug-in."""
        return self._stage

    @property
    def _contract(self) -> StageContract:
        return self._registry.contract

    def __repr__(self) -> str:
        return f"CheckedStage({self._name} plug-in {self._label!r}: {self._stage!r})"

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__") or name in ("_stage", "_registry", "_name", "_label", "_clock"):
            raise AttributeError(name)  # copying or unpickling: the instance is not set up yet
        if name == "take_users":
            if not takes_users(self._stage):
                raise AttributeError(
                    f"{self._name} plug-in {self._label!r} has no take_users (its users idle "
                    "to the batch's end instead)"
                )
            return self._take_users
        return getattr(self._stage, name)

    def reset(self, *args: Any, **kwargs: Any) -> None:
        """The plug-in's ``reset``; the reset users' clocks restart at 0."""
        self._call("reset", args, kwargs)
        if self._contract.clock is not None:
            rows = args[0] if args else kwargs.get(self._contract.calls["reset"][0][0])
            self._clock[stream_rows(rows, self._clock.size, unique=False)] = 0

    def _take_users(self, rows: ArrayLike) -> None:
        self._stage.take_users(rows)
        self._clock = self._clock[np.asarray(rows, dtype=np.intp)]

    def update(self, *args: Any, **kwargs: Any) -> Any:
        """The plug-in's ``update``, its result checked against the contract (keywords, such
        as the ``pitch=`` of a stage that declares ``uses_pitch``, passed on)."""
        contract = self._contract
        dims = contract.dims(args)
        out = self._call("update", args, kwargs)
        try:
            raw = contract.unpack(out, self._stage)
        except MalformedOutput as err:
            raise self._error(f"returned {err}; expected {contract.returns}") from None
        except Exception as err:
            raise self._error(f"raised reading its output: {type(err).__name__}: {err}") from err
        arrays = {o.name: self._array(o, raw[o.name], dims) for o in contract.outputs}
        context = {"clock": self._clock, "fs": self._rate_hz}
        for rule in contract.rules:
            broken = rule.broken(arrays, context)
            if broken.any():
                raise self._broken(rule, arrays[rule.output], broken)
        if contract.clock is not None:
            self._clock += dims[contract.clock]
        return contract.pack(arrays, out)

    def _call(self, method: str, args: tuple[Any, ...], kwargs: dict[str, Any]) -> Any:
        try:
            return getattr(self._stage, method)(*args, **kwargs)
        except StageError:
            raise
        except Exception as err:
            raise self._error(f"raised in {method}(): {type(err).__name__}: {err}") from err

    def _array(self, output: Output, value: Any, dims: dict[str, int]) -> NDArray[np.float64]:
        shape = tuple(dims[s] if isinstance(s, str) else s for s in output.shape)
        try:
            arr = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError):
            raise self._error(
                f"returned {type(value).__name__} for {output.name}; expected a {output.kind} "
                f"array of shape {shape}"
            ) from None
        if arr.shape != shape:
            raise self._error(f"returned {output.name} of shape {arr.shape}; expected {shape}")
        return arr

    def _broken(self, rule: Rule, value: NDArray[np.float64], broken: NDArray) -> StageError:
        output = next(o for o in self._contract.outputs if o.name == rule.output)
        at = tuple(int(i) for i in np.argwhere(broken)[0])
        where = ", ".join(f"{axis} {i}" for axis, i in zip(output.axes, at, strict=True))
        return self._error(
            f"returned {rule.output} at {where}: {_format_value(value[at])}, which breaks the "
            f"rule: {rule.text}"
        )

    def _error(self, what: str) -> StageError:
        return StageError(f"{self._name} plug-in {self._label!r} {what}")
