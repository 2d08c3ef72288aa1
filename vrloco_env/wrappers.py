"""Wrappers of the native vector env that keep its batch layout.

:class:`FrameStack` gives each user its last ``k`` observations side by side, oldest first, so
that a feed-forward policy sees a short history (velocities, what was in view a moment ago):
``FrameStack(VRLocoVectorEnv(32), 4)`` returns observations of shape ``(32, 4 * n)``. One
numpy operation per step shifts every user's frames; nothing loops over the users.
:class:`StackedFrames` is the per-user history itself, for a policy that stacks the frames of a
single env or of a batch it is handed (:class:`agents.benchmark.policies.LearnedPolicy`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorWrapper
from gymnasium.vector.utils import batch_space
from numpy.typing import ArrayLike, NDArray

from estimators.validation import check_value

__all__ = ["FrameStack", "StackedFrames", "check_frame_stack"]

#: The most frames :func:`check_frame_stack` accepts.
MAX_FRAME_STACK = 64


def check_frame_stack(k: Any, name: str = "frame_stack") -> int:
    """``k`` as the number of stacked frames: an integer in [1, :data:`MAX_FRAME_STACK`]
    (1: no history); a ValueError naming ``name`` otherwise."""
    check_value(name, k, 1, MAX_FRAME_STACK, integer=True)
    return int(k)


class StackedFrames:
    """The last ``k`` observations of each of ``B`` users, oldest first.

    A user's history starts with its episode's first observation repeated ``k`` times
    (gymnasium's ``FrameStackObservation`` pads the same way), so every entry is a real
    observation of that episode.

    Args:
        k: frames per user (>= 1).
        size: the length of one observation.
    """

    def __init__(self, k: int, size: int) -> None:
        self.k = check_frame_stack(k)
        self.size = int(size)
        self.frames = np.zeros((0, self.k, self.size), np.float32)

    @property
    def batch_size(self) -> int:
        return self.frames.shape[0]

    def start(self, obs: ArrayLike, rows: ArrayLike | None = None) -> None:
        """Start the histories of ``rows`` (None: every user, and the batch takes ``obs``'s
        size) from their first observations ``obs`` (B, size), one row per user of the batch."""
        obs = self._rows(obs)
        if rows is None:
            self.frames = np.repeat(obs[:, None, :], self.k, axis=1)
            return
        rows = np.asarray(rows)
        self.frames[rows] = obs[rows, None, :]

    def push(self, obs: ArrayLike) -> None:
        """Append every user's new observation (B, size), dropping its oldest."""
        obs = self._rows(obs)
        if obs.shape[0] != self.batch_size:
            raise ValueError(
                f"push: {obs.shape[0]} observations for a batch of {self.batch_size} users"
            )
        self.frames[:, :-1] = self.frames[:, 1:]  # numpy copies overlapping slices first
        self.frames[:, -1] = obs

    def stacked(self) -> NDArray[np.float32]:
        """Every user's frames side by side, oldest first: (B, k * size), a new array."""
        return self.frames.reshape(self.batch_size, self.k * self.size).copy()

    def take_users(self, rows: ArrayLike) -> None:
        """Keep the users ``rows`` (in their new order)."""
        self.frames = self.frames[np.asarray(rows, dtype=np.intp)]

    def _rows(self, obs: ArrayLike) -> NDArray[np.float32]:
        obs = np.asarray(obs, dtype=np.float32)
        if obs.ndim != 2 or obs.shape[1] != self.size:
            raise ValueError(f"observations of shape {obs.shape}: expected (users, {self.size})")
        return obs


class FrameStack(VectorWrapper):
    """A vector env whose observations are each user's last ``k`` observations side by side,
    oldest first: ``(num_envs, k * n)``, the layout of the wrapped env's batch kept.

    A user's history starts from its episode's first observation repeated ``k`` times, at every
    reset and at every autoreset. With ``SAME_STEP`` autoreset, ``infos["final_obs"]`` holds the
    finished episode's last ``k`` observations (the rows of the users whose episode ended), and
    the returned row is the new episode's first observation repeated. With autoreset disabled,
    ``reset(options={"reset_mask": mask})`` starts the masked users' histories again.

    Args:
        env: a :class:`~vrloco_env.vector.VRLocoVectorEnv` (or another vector env with a flat
            ``Box`` observation and ``final_obs`` in its infos).
        k: frames per user (1: the observation as it is).
    """

    def __init__(self, env: Any, k: int) -> None:
        super().__init__(env)
        space = env.single_observation_space
        if not isinstance(space, spaces.Box) or len(space.shape) != 1:
            raise ValueError(f"FrameStack needs a flat Box observation, got {space}")
        self.k = check_frame_stack(k, "k")
        self._frames = StackedFrames(self.k, space.shape[0])
        self.single_observation_space = spaces.Box(
            np.tile(space.low, self.k), np.tile(space.high, self.k), dtype=space.dtype
        )
        self.observation_space = batch_space(self.single_observation_space, env.num_envs)

    def reset(self, *, seed: Any = None, options: dict[str, Any] | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        mask = (options or {}).get("reset_mask")
        self._frames.start(obs, None if mask is None else np.flatnonzero(mask))
        return self._frames.stacked(), info

    def step(self, actions: Any):
        obs, reward, terminated, truncated, info = self.env.step(actions)
        ended = info.get("_final_obs")
        if ended is None or not np.any(ended):
            self._frames.push(obs)
            return self._frames.stacked(), reward, terminated, truncated, info
        ended = np.asarray(ended, bool)
        # the finished users' last frame is their episode's last observation
        self._frames.push(np.where(ended[:, None], info["final_obs"], obs))
        info = dict(info)
        info["final_obs"] = np.where(ended[:, None], self._frames.stacked(), 0.0).astype(np.float32)
        self._frames.start(obs, np.flatnonzero(ended))
        return self._frames.stacked(), reward, terminated, truncated, info

    @property
    def autoreset_mode(self) -> AutoresetMode:
        return self.env.autoreset_mode

    @property
    def can_take_users(self) -> bool:
        return bool(getattr(self.env, "can_take_users", False))

    def take_users(self, rows: Any) -> None:
        """Keep the users ``rows`` (:meth:`VRLocoVectorEnv.take_users
        <vrloco_env.vector.VRLocoVectorEnv.take_users>`), their histories with them."""
        self.env.take_users(rows)
        self._frames.take_users(rows)
        self.observation_space = batch_space(self.single_observation_space, self.env.num_envs)
