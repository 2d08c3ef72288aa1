"""Plug your own simulated user into vrloco: walk toward the goal, stop short of what is ahead.

    python examples/custom_policy.py     # three users of the Avoid corridor, batched
    vrloco benchmark --tasks avoid --policies examples/custom_policy.py:CautiousWalker \\
        --techniques zhang2021 --episodes 4 --out out/custom_policy

A policy is built as ``Cls(env)`` (any ``factory(env)``) and has ``reset(rng=None, rows=None)``
and ``act(obs) -> action`` (:class:`agents.scripted.Policy`): one observation ``(n,)`` gives one
action ``(5,)``, a batch ``(B, n)`` gives ``(B, 5)``, float32 in [-1, 1] ``[walk, turn,
hand_yaw_rate, hand_pitch_rate, hand_roll_rate]`` (:mod:`vrloco_env.actions`). It reads the
observation only, decoded with :class:`agents.scripted.ObsView`: what the headset shows (the goal
bearing and distance, the rays from the virtual head), never the ground truth in ``info``.
``batched = True`` lets the benchmark run its episodes as the users of one vector env;
subclassing :class:`~estimators.batching.TakesUsers` and naming the per-user attributes lets it
drop the users whose episodes have ended. ``--policies examples/custom_policy.py:CautiousWalker``
(or ``package.module:CautiousWalker``) selects it, ``+typical`` after it adds a human
population's reaction delay and jitter (:mod:`agents.benchmark.policies`).

Direct use, three users at once::

    env = gym.make_vec("VRLoco-Avoid-v0", num_envs=3, vectorization_mode="vector_entry_point")
    policy = CautiousWalker(env)
    obs, info = env.reset(seed=[0, 1, 2])
    policy.reset()
    for _ in range(100):
        obs, reward, terminated, truncated, info = env.step(policy.act(obs))
"""

from __future__ import annotations

import numpy as np

from agents.scripted import ObservationLayout, ObsView
from estimators.batching import TakesUsers


class CautiousWalker(TakesUsers):
    """Turn toward the goal bearing and walk along it while the rays ahead are long; stop as soon
    as one of them is shorter than ``stop_m``, and start again only once all are at least
    ``go_m`` (walking in place cannot stop at once: the steps under way still land, so ``go_m``
    leaves room for the two step lengths a bout starts with). A ray longer than the way to the
    goal region (plus ``goal_margin_m``) never stops it. It does not go round anything: in front
    of an obstacle it stands still, facing the goal. Inside the goal region it stands still.

    Args:
        env: the env it plays (a ``gym.make`` env or a ``vector_entry_point`` vector env).
        stop_m: stop when a ray within ``front_deg`` of the heading is shorter than this (m).
        go_m: (re)start only when every such ray is at least this long (m).
        front_deg: half-width of the fan of rays that count as "in front" (deg).
        aligned_deg: walk only when the goal bearing is within this of the heading (deg).
        walk: the walk action while walking (0.5: 1.7 steps/s).
        turn_gain: turn action per radian of goal bearing (1/rad).
        goal_margin_m: a ray this much longer than the way to the goal does not stop it (m).
    """

    batched = True
    per_user_fields = ("walking",)

    def __init__(
        self,
        env,
        stop_m: float = 1.6,
        go_m: float = 2.2,
        front_deg: float = 20.0,
        aligned_deg: float = 15.0,
        walk: float = 0.5,
        turn_gain: float = 1.2,
        goal_margin_m: float = 0.5,
    ) -> None:
        if not 0.0 < stop_m <= go_m:
            raise ValueError(f"need 0 < stop_m <= go_m, got stop_m={stop_m}, go_m={go_m}")
        self.layout = ObservationLayout.from_env(env)
        self.front = np.abs(self.layout.ray_offsets) <= np.deg2rad(front_deg)  # (R,)
        if not self.front.any():
            raise ValueError(f"front_deg={front_deg}: no ray within it of the heading")
        self.stop_m, self.go_m, self.aligned = stop_m, go_m, np.deg2rad(aligned_deg)
        self.walk, self.turn_gain, self.goal_margin_m = walk, turn_gain, goal_margin_m
        self.walking = np.zeros(0, bool)  # (B,): the user is walking

    def reset(self, rng=None, rows=None) -> None:
        """New episodes for ``rows`` of the batch (None: every user; the batch size is then
        taken from the next ``act``)."""
        if rows is None:
            self.walking = np.zeros(0, bool)
        else:
            self.walking[np.asarray(rows, dtype=np.intp)] = False

    def act(self, obs) -> np.ndarray:
        o = np.asarray(obs, dtype=np.float64)
        single = o.ndim == 1
        o = np.atleast_2d(o)
        if self.walking.shape[0] != o.shape[0]:
            self.walking = np.zeros(o.shape[0], bool)
        v = ObsView.decode(o, self.layout)
        ahead = v.rays[:, self.front].min(axis=1)  # (B,) the shortest ray in front (m)
        goal_first = ahead >= v.distance + self.goal_margin_m  # the goal comes before the hit
        aligned = np.abs(v.bearing) < self.aligned
        in_goal = v.distance <= 0.0
        start = ~self.walking & aligned & ((ahead >= self.go_m) | goal_first)
        keep = self.walking & aligned & ((ahead >= self.stop_m) | goal_first)
        self.walking = (start | keep) & ~in_goal
        action = np.zeros((o.shape[0], 5), np.float32)
        action[:, 0] = np.where(self.walking, self.walk, -1.0)
        action[:, 1] = np.where(in_goal, 0.0, np.clip(self.turn_gain * v.bearing, -1.0, 1.0))
        return action[0] if single else action


if __name__ == "__main__":
    import gymnasium as gym

    import vrloco_env  # noqa: F401  (registers the ids)

    env = gym.make_vec("VRLoco-Avoid-v0", num_envs=3, vectorization_mode="vector_entry_point")
    policy = CautiousWalker(env)
    obs, info = env.reset(seed=[0, 1, 2])
    policy.reset()
    start = info["position"]
    collisions = np.zeros(3, np.int64)
    for _ in range(150):
        obs, _, terminated, truncated, info = env.step(policy.act(obs))
        collisions = info["collisions"]
    ahead = ObsView.decode(obs.astype(np.float64), policy.layout).rays[:, policy.front].min(1)
    for i in range(3):
        print(
            f"user {i}: walked {info['position'][i][0] - start[i][0]:.2f} m down the corridor, "
            f"stopped {ahead[i]:.2f} m short of the obstacle, {collisions[i]} collisions"
        )
    env.close()
