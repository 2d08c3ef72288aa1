"""A vector env's users stepped in worker processes, a share of the batch each, so that the
environment's step — most of a training loop's time — runs on several cores.

:func:`parallel_users` splits ``num_envs`` users between ``workers`` processes
(:class:`RemoteUsers`, each holding a :class:`~vrloco_env.vector.VRLocoVectorEnv` of its share)
and joins them with :class:`~agents.learned.mixed_env.MixedUsersEnv`, which sends every share
its actions before it waits for any. A user's episode depends on its own seed only (a vector env
seeds user ``i`` with ``seed + i``, and the mix seeds each share from its first user), so the
joined env gives exactly the observations, rewards and infos of one vector env of all the users:
a training run learns the same weights with any number of workers.

The workers are spawned (a forked child of a process that has started torch's threads can hang)
and load the env's compiled kernels from numba's cache. Each step sends the actions and returns
the share's observations, rewards, ends and info through a pipe.
"""

from __future__ import annotations

import multiprocessing as mp
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode

__all__ = ["RemoteUsers", "parallel_users"]


def _serve(conn: Any, num_envs: int, env_kwargs: dict[str, Any]) -> None:
    """A worker: one vector env of ``num_envs`` users, driven by the commands on ``conn``."""
    from vrloco_env.vector import VRLocoVectorEnv

    env = VRLocoVectorEnv(num_envs, **env_kwargs)
    conn.send((env.observation_spec, env.task_name, env.single_action_space))
    try:
        while True:
            command, data = conn.recv()
            if command not in ("step", "reset"):
                break
            try:
                answer = env.step(data) if command == "step" else env.reset(**data)
            except Exception as err:  # the env's own error, raised again in the caller
                conn.send(("error", err))
            else:
                conn.send(("ok", answer))
    except (EOFError, KeyboardInterrupt):
        pass
    finally:
        env.close()
        conn.close()


class RemoteUsers(gym.vector.VectorEnv):
    """``num_envs`` users of a :class:`~vrloco_env.vector.VRLocoVectorEnv` built from
    ``env_kwargs`` in a worker process; ``step_async``/``step_wait`` let several of them step at
    once (:class:`~agents.learned.mixed_env.MixedUsersEnv` does)."""

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP, "render_modes": []}  # noqa: RUF012

    def __init__(self, num_envs: int, env_kwargs: dict[str, Any]) -> None:
        context = mp.get_context("spawn")
        self._conn, child = context.Pipe()
        self._process = context.Process(
            target=_serve, args=(child, int(num_envs), env_kwargs), daemon=True
        )
        self._process.start()
        child.close()
        self.observation_spec, self.task_name, self.single_action_space = self._conn.recv()
        self.num_envs = int(num_envs)
        size = self.observation_spec.size
        self.single_observation_space = gym.spaces.Box(-1.0, 1.0, (size,), np.float32)
        self.action_space = gym.vector.utils.batch_space(self.single_action_space, num_envs)
        self.observation_space = gym.vector.utils.batch_space(
            self.single_observation_space, num_envs
        )
        self.autoreset_mode = AutoresetMode.SAME_STEP

    def reset_async(self, *, seed: Any = None, options: Any = None) -> None:
        self._conn.send(("reset", {"seed": seed, "options": options}))

    def step_async(self, actions: Any) -> None:
        self._conn.send(("step", np.asarray(actions)))

    def wait(self) -> Any:
        """The worker's answer to the last command; the env's error there is raised here."""
        status, answer = self._conn.recv()
        if status == "error":
            raise answer
        return answer

    def reset(self, *, seed: Any = None, options: Any = None) -> tuple[Any, dict]:
        self.reset_async(seed=seed, options=options)
        return self.wait()

    def step(self, actions: Any) -> tuple[Any, Any, Any, Any, dict]:
        self.step_async(actions)
        return self.wait()

    def close(self, **kwargs: Any) -> None:
        if self._process.is_alive():
            try:
                self._conn.send(("close", None))
            except (BrokenPipeError, OSError):
                pass
            self._process.join(timeout=5)
            if self._process.is_alive():
                self._process.terminate()
        self._conn.close()


def parallel_users(num_envs: int, workers: int, env_kwargs: dict[str, Any]) -> Any:
    """``num_envs`` users of the env ``env_kwargs`` (the keywords of
    :class:`~vrloco_env.vector.VRLocoVectorEnv`) stepped in ``workers`` processes, as one
    vector env (module docstring).

    Raises:
        ValueError: ``workers`` below 1 or above ``num_envs``.
    """
    from agents.learned.mixed_env import MixedUsersEnv, split_users

    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"env_workers={workers!r}: must be an integer >= 1")
    shares = split_users(num_envs, workers, "num_envs")
    parts = []
    try:
        for n in shares:
            parts.append(RemoteUsers(n, env_kwargs))
    except BaseException:
        for part in parts:
            part.close()
        raise
    return MixedUsersEnv(parts, [f"worker {i}" for i in range(workers)])
