"""What a scripted user reads: the observation decoded into physical units, and the rays.

* :class:`ObservationLayout` — the env's :class:`~vrloco_env.observation.ObservationSpec` (entries,
  scales, the decoder) and the directions of its rays.
* :class:`ObsView` — a batch of observations decoded into the virtual heading, the goal bearing and
  distance, the ray ranges seen from the *virtual* pose (what the headset shows), the detected
  steps, for Interact the hand error and, with a user population that turns the head, the head's
  yaw on the torso.
* :func:`ray_points`, :func:`free_lengths` — the obstacle points the rays see in the body frame,
  and how far the user's disc can move along each heading before touching one.
* ``_check_obs`` (observation shape and finiteness), shared by the policies.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from vrloco_env.config import EnvConfig
from vrloco_env.observation import ObservationSpec, env_spec, ray_offsets

__all__ = ["ObsView", "ObservationLayout", "free_lengths", "ray_points"]


class ObservationLayout:
    """What a policy knows of the observation: the env's :class:`ObservationSpec` (entries,
    scales, the decoder) and the directions of its rays.

    Args:
        spec: the env's observation spec (``env.unwrapped.observation_spec``).
        ray_offsets: ray directions relative to the heading (rad, counter-clockwise).
    """

    def __init__(self, spec: ObservationSpec, ray_offsets: ArrayLike) -> None:
        self.spec = spec
        self.ray_offsets = np.asarray(ray_offsets, dtype=np.float64)
        if "rays" not in spec or spec.field("rays").size != self.ray_offsets.size:
            raise ValueError("ray_offsets must give one direction per ray of the spec")
        self.ray_count = self.ray_offsets.size
        self.ray_range_m = spec.field("rays").scale

    @classmethod
    def from_config(
        cls, config: EnvConfig | None = None, task: str = "approach", task_config: Any = None
    ) -> ObservationLayout:
        """The layout of envs of ``task`` built with ``config`` (defaults if None)."""
        from vrloco_env.observation import population_fields
        from vrloco_env.tasks import get_task

        config = config or EnvConfig()
        fields = (
            *get_task(task)(1, 0.1, task_config).fields(),
            *population_fields(config.population),
        )
        spec = env_spec(config.ray_count, config.ray_range_m, fields)
        return cls(spec, ray_offsets(config.ray_count, config.ray_fov_deg))

    @classmethod
    def from_env(cls, env: Any) -> ObservationLayout:
        """The layout of a ``gym.make``-built env (or its vector twin)."""
        core = env.unwrapped.core
        return cls(core.spec, core.ray_offsets)

    @property
    def names(self) -> list[str]:
        return self.spec.names

    @property
    def size(self) -> int:
        return self.spec.size

    def index(self, name: str) -> int:
        return self.spec.index(name)


@dataclass
class ObsView:
    """A batch of observations decoded into physical units (arrays over B rows).

    Attributes:
        heading: virtual heading (rad).
        walking: the gait detector says walking.
        steps: steps detected in the last control step (the entry saturates at 3).
        bearing: goal bearing relative to the heading (rad, counter-clockwise positive).
        distance: distance to the goal region (m); 0 inside it.
        waypoint: straight distance (m) to the point the bearing points at: the task's
            ``waypoint_distance`` where it has one (Doorway: the next doorway), else ``distance``.
        rays: ray ranges (m), (B, R).
        hand_error: target minus estimated hand [yaw, pitch, roll] (rad), (B, 3).
        hand_valid: a hand estimate exists.
        dwell: fraction of the Interact dwell time held so far.
        head_on_torso: the head's yaw relative to the torso (rad), from the observation's
            ``head_on_torso`` field where a user population turns the head (0 without it).
        moved: the virtual body's displacement in the last control step (m), (B, 2), along and
            across the heading (the observation's ``self_motion``).
    """

    heading: NDArray[np.float64]
    walking: NDArray[np.bool_]
    steps: NDArray[np.float64]
    bearing: NDArray[np.float64]
    distance: NDArray[np.float64]
    waypoint: NDArray[np.float64]
    rays: NDArray[np.float64]
    hand_error: NDArray[np.float64]
    hand_valid: NDArray[np.bool_]
    dwell: NDArray[np.float64]
    head_on_torso: NDArray[np.float64]
    moved: NDArray[np.float64]

    @classmethod
    def decode(cls, obs: NDArray[np.float64], layout: ObservationLayout) -> ObsView:
        """Decode ``(B, n)`` observations with the env's spec (tasks without a hand target
        read a zero hand error and dwell)."""
        d = layout.spec.decode(obs)
        b = obs.shape[0]
        return cls(
            heading=np.arctan2(d["heading"][:, 0], d["heading"][:, 1]),
            walking=d["walking"][:, 0] > 0.5,
            steps=np.rint(d["steps"][:, 0]),
            bearing=np.arctan2(d["goal_bearing"][:, 0], d["goal_bearing"][:, 1]),
            distance=d["goal_distance"][:, 0],
            waypoint=d.get("waypoint_distance", d["goal_distance"])[:, 0],
            rays=d["rays"],
            hand_error=d["hand_error"] if "hand_error" in d else np.zeros((b, 3)),
            hand_valid=d["hand_valid"][:, 0] > 0.5,
            dwell=d["dwell"][:, 0] if "dwell" in d else np.zeros(b),
            head_on_torso=d["head_on_torso"][:, 0] if "head_on_torso" in d else np.zeros(b),
            moved=d["self_motion"],
        )


def _check_obs(obs: ArrayLike, layout: ObservationLayout) -> tuple[NDArray[np.float64], bool]:
    """The observations as ``(B, n)`` float64 and whether a single one was given."""
    o = np.asarray(obs, dtype=np.float64)
    single = o.ndim == 1
    if single:
        o = o[None]
    if o.ndim != 2 or o.shape[1] != layout.size:
        raise ValueError(
            f"obs must have shape ({layout.size},) or (B, {layout.size}) for "
            f"{layout.ray_count} rays, got {np.shape(obs)}"
        )
    if not np.all(np.isfinite(o)):
        raise ValueError("obs must be finite (an env observation lies in [-1, 1])")
    return o, single


# --------------------------------------------------------------------------- ray geometry


def ray_points(
    rays: NDArray[np.float64], offsets: NDArray[np.float64], range_m: float
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Obstacle points seen by the rays, in the body frame (x ahead, y left).

    Args:
        rays: ray ranges (m), (B, R).
        offsets: ray directions relative to the heading (rad), (R,).
        range_m: ray range (m); a ray this long saw nothing.

    Returns:
        points (B, R, 2) (m) and which of them are hits (B, R).
    """
    hit = rays < range_m * (1.0 - 1e-4)
    return rays[..., None] * np.stack([np.cos(offsets), np.sin(offsets)], -1), hit


def free_lengths(
    points: NDArray[np.float64],
    valid: NDArray[np.bool_],
    angles: NDArray[np.float64],
    half_width: float,
    max_length: float,
) -> NDArray[np.float64]:
    """How far a disc of radius ``half_width`` can move from the origin along each heading.

    Args:
        points: obstacle points in the body frame (m), (B, P, 2).
        valid: which points are real, (B, P).
        angles: headings relative to the body x axis (rad), (C,) for every row or (B, C).
        half_width: disc radius (m): the avatar's radius plus a margin.
        max_length: the length reported when nothing blocks (m).

    Returns:
        Free lengths (m), (B, C), in [0, max_length]. A point already closer than
        ``half_width`` blocks only the headings that would bring the body closer to it: the user
        may always move away from, or along, what they stand next to.
    """
    ang = np.asarray(angles, dtype=np.float64)
    if ang.ndim == 1:
        ang = np.broadcast_to(ang, (points.shape[0], ang.size))
    if ang.ndim != 2 or ang.shape[0] != points.shape[0]:
        raise ValueError(f"angles must have shape (C,) or (B, C), got {np.shape(angles)}")
    ux, uy = np.cos(ang)[:, None, :], np.sin(ang)[:, None, :]  # (B, 1, C)
    px, py = points[..., 0:1], points[..., 1:2]  # (B, P, 1)
    along = px * ux + py * uy
    lat = np.abs(px * uy - py * ux)
    rad = np.minimum(np.hypot(px, py) - 1e-3, half_width)
    half_chord = np.sqrt(np.maximum(rad**2 - lat**2, 0.0))
    blocks = valid[..., None] & (lat < rad) & (along > 0.0)
    first = np.where(blocks, np.maximum(along - half_chord, 0.0), np.inf).min(axis=1)
    return np.minimum(first, max_length)
