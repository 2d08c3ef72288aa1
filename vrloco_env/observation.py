"""The observation, declared once: ordered fields, each with its entries, scale and unit.

An :class:`ObservationSpec` is the single description of the observation vector. It gives the
entry names (``spec.names``), the offsets and scales the compiled observation kernel writes with
(``spec.offset``, ``spec.scales``), and the decoder a policy reads physical values back with
(``spec.decode(obs)["goal_distance"]`` in metres). Every entry is ``clip(value / scale, -1, 1)``
of a physical value, so ``decode`` is a multiplication (exact inside the range; saturated
entries read the scale).

The env's spec is :func:`env_spec` of its configuration: the fields every task shares
(:data:`COMMON_FIELDS`) followed by the task's own (:meth:`vrloco_env.tasks.Task.fields`) and,
with a user population whose head turns on the torso, :data:`HEAD_ON_TORSO`
(:func:`population_fields`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.validation import check_value

__all__ = [
    "COMMON_FIELDS",
    "HEAD_ON_TORSO",
    "MAX_GOAL_DISTANCE",
    "Field",
    "ObservationSpec",
    "env_spec",
    "population_fields",
    "ray_offsets",
]

#: Goal distance (m) that the observation scales to 1 (farther goals read 1).
MAX_GOAL_DISTANCE = 20.0


@dataclass(frozen=True)
class Field:
    """One field of the observation.

    Attributes:
        name: the field's name (``"rays"``).
        entries: the names of its entries, in order (``("ray_0", "ray_1", ...)``); one entry
            named like the field if omitted.
        scale: the physical value an entry reads as 1 (``obs = clip(value / scale, -1, 1)``).
        unit: the physical unit (``"m"``, ``"rad"``, ``""`` for a ratio or a flag).
        doc: one line on what it is.
    """

    name: str
    entries: tuple[str, ...] = ()
    scale: float = 1.0
    unit: str = ""
    doc: str = ""

    def __post_init__(self) -> None:
        if not self.entries:
            object.__setattr__(self, "entries", (self.name,))
        check_value(f"Field({self.name!r}).scale", self.scale, 0.0, math.inf, lo_open=True)

    @property
    def size(self) -> int:
        return len(self.entries)


class ObservationSpec:
    """Ordered fields; see the module docstring.

    Args:
        fields: the fields, in observation order (names and entry names unique).
    """

    def __init__(self, fields: Sequence[Field]) -> None:
        self.fields = tuple(fields)
        names = [e for f in self.fields for e in f.entries]
        if len(set(names)) != len(names) or len({f.name for f in self.fields}) != len(self.fields):
            raise ValueError(f"observation fields and entries must be unique, got {names}")
        self.names: list[str] = names
        self.size = len(names)
        self._offsets: dict[str, int] = {}
        scales = []
        at = 0
        for f in self.fields:
            self._offsets[f.name] = at
            at += f.size
            scales += [float(f.scale)] * f.size
        self.scales = np.array(scales)
        self._index = {n: i for i, n in enumerate(names)}

    def __contains__(self, name: object) -> bool:
        return name in self._offsets

    def field(self, name: str) -> Field:
        """The field called ``name``."""
        for f in self.fields:
            if f.name == name:
                return f
        raise KeyError(f"no observation field {name!r}; fields: {', '.join(self._offsets)}")

    def offset(self, name: str) -> int:
        """Index of the first entry of field ``name``."""
        if name not in self._offsets:
            raise KeyError(f"no observation field {name!r}; fields: {', '.join(self._offsets)}")
        return self._offsets[name]

    def slice(self, name: str) -> slice:
        """The entries of field ``name``."""
        start = self.offset(name)
        return slice(start, start + self.field(name).size)

    def index(self, entry: str) -> int:
        """Index of the entry called ``entry`` (``"ray_3"``)."""
        if entry not in self._index:
            raise KeyError(f"no observation entry {entry!r}")
        return self._index[entry]

    def decode(self, obs: ArrayLike) -> dict[str, NDArray[np.float64]]:
        """Physical values of (B, size) or (size,) observations: field -> (B, field size)
        (or (field size,) for one observation)."""
        o = np.asarray(obs, dtype=np.float64)
        if o.shape[-1:] != (self.size,):
            raise ValueError(f"obs must have {self.size} entries, got shape {o.shape}")
        phys = o * self.scales
        return {f.name: phys[..., self.slice(f.name)] for f in self.fields}

    def encode(self, name: str, values: ArrayLike, out: NDArray[np.float32]) -> None:
        """Write physical ``values`` (B, field size) of field ``name`` into ``out`` (B, size),
        scaled and clipped."""
        sl = self.slice(name)
        v = np.asarray(values, dtype=np.float64) / self.scales[sl]
        out[:, sl] = np.minimum(np.maximum(v, -1.0), 1.0)

    def describe(self) -> str:
        """One line per field: name, entries, scale and unit."""
        lines = []
        for f in self.fields:
            span = f.entries[0] if f.size == 1 else f"{f.entries[0]}..{f.entries[-1]}"
            lines.append(
                f"{f.name:<14} [{self.offset(f.name):>2}] {span:<28} "
                f"x {f.scale:g} {f.unit:<8} {f.doc}"
            )
        return "\n".join(lines)


#: The fields every task observes, in order (the compiled kernel's layout, by name).
COMMON_FIELDS = (
    "heading",
    "pitch",
    "roll",
    "walking",
    "steps",
    "cadence",
    "self_motion",
    "hand",
    "hand_valid",
    "goal_bearing",
    "goal_distance",
    "rays",
)


def env_spec(
    ray_count: int, ray_range_m: float, task_fields: Sequence[Field] = ()
) -> ObservationSpec:
    """The env's observation: the common fields for ``ray_count`` rays of ``ray_range_m``, then
    the task's ``task_fields``."""
    common = (
        Field(
            "heading",
            ("heading_sin", "heading_cos"),
            1.0,
            "",
            "virtual heading (the estimated yaw in the room) as sin, cos",
        ),
        Field("pitch", scale=math.pi / 2, unit="rad", doc="estimated head pitch"),
        Field("roll", scale=math.pi, unit="rad", doc="estimated head roll"),
        Field("walking", doc="the step detector's still (0) / walk (1) state"),
        Field("steps", scale=3.0, unit="steps", doc="steps detected in the last control step"),
        Field("cadence", scale=3.0, unit="steps/s", doc="estimated cadence"),
        Field(
            "self_motion",
            ("moved_forward", "moved_left"),
            2.0,
            "m",
            "the virtual body's displacement in the last control step along and across the "
            "virtual heading: the self-motion the user sees (0 for a blocked step)",
        ),
        Field(
            "hand",
            ("hand_yaw", "hand_pitch", "hand_roll"),
            math.pi,
            "rad",
            "estimated hand orientation relative to the torso (0 without estimate)",
        ),
        Field("hand_valid", doc="a hand estimate exists (1) or not (0)"),
        Field(
            "goal_bearing",
            ("goal_bearing_sin", "goal_bearing_cos"),
            1.0,
            "",
            "goal direction relative to the virtual heading as sin, cos",
        ),
        Field(
            "goal_distance",
            scale=MAX_GOAL_DISTANCE,
            unit="m",
            doc="distance from the virtual body to the goal region",
        ),
        Field(
            "rays",
            tuple(f"ray_{k}" for k in range(ray_count)),
            float(ray_range_m),
            "m",
            "ranges along the rays from the virtual head",
        ),
    )
    assert tuple(f.name for f in common) == COMMON_FIELDS
    return ObservationSpec((*common, *task_fields))


#: The head's true yaw on the torso: what a user knows by proprioception of where their head
#: points relative to their body (the view turns with the head; the turn action turns the body).
HEAD_ON_TORSO = Field(
    "head_on_torso",
    scale=math.pi / 2,
    unit="rad",
    doc="the head's yaw relative to the torso (proprioception)",
)


def population_fields(population: object) -> tuple[Field, ...]:
    """The observation fields a user population adds: :data:`HEAD_ON_TORSO` where its head
    turns on the torso (``Population.gaze``), none otherwise (None: no population)."""
    if population is None:
        return ()
    from vrloco_env.user.population import get_population

    return (HEAD_ON_TORSO,) if get_population(population).gaze else ()


def ray_offsets(ray_count: int, ray_fov_deg: float) -> NDArray[np.float64]:
    """Directions (rad, counter-clockwise from the virtual heading) of ``ray_count`` rays spread
    evenly over ``ray_fov_deg`` (a full circle without repeating the back ray; one ray: ahead)."""
    if ray_count == 1:
        return np.zeros(1)
    if ray_fov_deg >= 360.0:
        return np.linspace(-np.pi, np.pi, ray_count, endpoint=False)
    half = np.deg2rad(ray_fov_deg) / 2.0
    return np.linspace(-half, half, ray_count)
