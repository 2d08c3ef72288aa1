"""A learned user's first policy imitated from a scripted user (DAgger), for PPO to go on from.

PPO from a random policy has to find, by chance, the way to stop short of a wall in a room it
sees through the estimators; a scripted user such as the goal seeker already does that. The
learner can start from it instead: :func:`imitate` collects the users' observations as the PPO
policy will see them (frame stack and population included), labels each with the action the
scripted user takes there, and fits the policy's Gaussian to those actions by maximum likelihood
(its mean to the actions by least squares, its spread to what the mean leaves unexplained).
Rounds follow DAgger (Ross, Gordon & Bagnell 2011, "A reduction of imitation learning and
structured prediction to no-regret online learning"): the first round the scripted user acts; in
round ``i`` each step's action is the scripted user's with probability ``0.5 ** i`` and otherwise
one drawn from the learner's Gaussian, so the data come more and more from the states the learner
itself reaches, still labelled by the scripted user. The last round's returns (discounted by
PPO's ``gamma``, episodes that ended within the round only) fit the value function, so that PPO's
first advantages are not those of an untrained critic.

The scripted user acts on the same observation the learner sees (its latest frame); it keeps its
own memory (the goal seeker's map), which the learner has to replace with what its frames show.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from vrloco_env.actions import ACTION_SIZE

__all__ = [
    "BodyTeachers",
    "EpisodeTally",
    "check_imitation",
    "episode_returns",
    "imitate",
    "imitate_scripted",
    "scripted_teacher",
]

#: The smallest log standard deviation the fitted Gaussian may take: an action the scripted user
#: never varies (the hand on a task without a hand target) would otherwise drive its spread to
#: zero and PPO could never explore it again. A choice: a standard deviation of e ** -3 ~ 0.05 on
#: actions in [-1, 1].
MIN_LOG_STD = -3.0


def imitate(
    model: Any,
    env: Any,
    teacher: Any,
    steps: int,
    *,
    rounds: int = 4,
    epochs: int = 10,
    batch_size: int = 2048,
    learning_rate: float = 1e-3,
    seed: int = 0,
) -> list[dict[str, float]]:
    """Fit ``model``'s policy (and value function) to ``teacher`` acting in ``env``, in place.

    Args:
        model: a stable-baselines3 ``PPO`` (feed-forward policy with a diagonal Gaussian).
        env: the users as the policy sees them (a vector env, same-step autoreset, frame stack
            and population wrappers included), ``num_envs`` users.
        teacher: a batched scripted user (``reset(rows=...)``, ``act(obs)``) whose observation
            layout is the env's unstacked observation: it sees the last ``n`` entries of each
            policy observation, ``n`` its layout's size.
        steps: environment steps in all (every user's steps counted), split evenly over the
            rounds and rounded up to whole steps of the batch.
        rounds: DAgger rounds (>= 1); in round ``i`` the teacher acts with probability
            ``0.5 ** i``.
        epochs: passes over all data so far after each round.
        batch_size: samples per gradient step.
        learning_rate: Adam's step size for the imitation (the model's own optimiser is not
            touched).
        seed: seeds the env's first reset and the mixing of the rounds' actions.

    Returns:
        Per round: the teacher's share of the actions, the round's success rate, collision rate
        and episodes (ended in the round), and the mean negative log-likelihood after fitting.

    Raises:
        ValueError: bad ``steps``, ``rounds``, ``epochs`` or ``batch_size``; a recurrent model;
            a teacher whose layout does not fit the env's observation.
    """
    import torch

    for name, value, low in (("steps", steps, 1), ("rounds", rounds, 1), ("epochs", epochs, 1)):
        if isinstance(value, bool) or not isinstance(value, int) or value < low:
            raise ValueError(f"{name}={value!r}: must be an integer >= {low}")
    if isinstance(batch_size, bool) or not isinstance(batch_size, int) or batch_size < 1:
        raise ValueError(f"batch_size={batch_size!r}: must be an integer >= 1")
    policy = model.policy
    if getattr(policy, "lstm_actor", None) is not None:
        raise ValueError("imitate fits a feed-forward policy; a recurrent one is not supported")
    n_envs = env.num_envs
    width = env.single_observation_space.shape[0]
    n_obs = teacher.layout.size
    if width % n_obs:
        raise ValueError(
            f"the teacher's observation has {n_obs} entries; the env's {width} are not whole "
            "frames of it"
        )
    per_round = -(-steps // (rounds * n_envs))  # batch steps per round
    rng = np.random.default_rng(seed)
    optimiser = torch.optim.Adam(policy.parameters(), lr=learning_rate)
    gamma = float(model.gamma)
    seen: list[np.ndarray] = []
    labels: list[np.ndarray] = []
    report: list[dict[str, float]] = []
    obs, _ = env.reset(seed=seed)
    teacher.reset()
    for r in range(rounds):
        share = 0.5**r
        o_round = np.empty((per_round, n_envs, width), np.float32)
        a_round = np.empty((per_round, n_envs, env.single_action_space.shape[0]), np.float32)
        rewards = np.empty((per_round, n_envs))
        ends = np.empty((per_round, n_envs), bool)
        tally = EpisodeTally(n_envs)
        for t in range(per_round):
            label = np.asarray(teacher.act(obs[:, -n_obs:]), np.float32)
            o_round[t], a_round[t] = obs, label
            if share < 1.0:
                with torch.no_grad():
                    own, _, _ = policy(torch.as_tensor(obs, device=policy.device))
                own = np.clip(own.cpu().numpy(), -1.0, 1.0)
                action = np.where(rng.random(n_envs)[:, None] < share, label, own)
            else:
                action = label
            obs, reward, terminated, truncated, info = env.step(action)
            done = terminated | truncated
            rewards[t], ends[t] = reward, done
            tally.add(done, info)
            if done.any():
                teacher.reset(rows=np.flatnonzero(done))
        seen.append(o_round.reshape(-1, width))
        labels.append(a_round.reshape(-1, a_round.shape[-1]))
        nll = _fit_policy(policy, optimiser, seen, labels, epochs, batch_size, rng)
        report.append(
            {
                "round": r,
                "teacher_share": share,
                **tally.rates(),
                "nll": nll,
            }
        )
    _fit_values(policy, optimiser, o_round, rewards, ends, gamma, epochs, batch_size, rng)
    return report


class EpisodeTally:
    """The episodes that end in a run of a vector env's steps (``n`` users): how many, how many
    succeeded and how many had a collision."""

    def __init__(self, n: int) -> None:
        self.hit = np.zeros(n, bool)  # the user's episode so far had a collision
        self.success = self.collided = self.episodes = 0

    def add(self, done: np.ndarray, info: dict[str, Any]) -> None:
        """Count one step: ``done`` (B,) the episodes it ended, ``info`` its per-user info."""
        self.hit |= info["collision"]
        self.success += int(np.sum(done & info["is_success"]))
        self.collided += int(np.sum(done & self.hit))
        self.episodes += int(np.sum(done))
        self.hit[done] = False

    def rates(self) -> dict[str, float]:
        """``episodes`` ended, their ``success_rate`` and ``collision_rate``."""
        n = max(self.episodes, 1)
        return {
            "episodes": self.episodes,
            "success_rate": self.success / n,
            "collision_rate": self.collided / n,
        }


def check_imitation(
    imitate: str,
    init: Any = None,
    recurrent: bool = False,
    cells: Any = (),
    env_workers: int = 1,
) -> None:
    """Whether a training run can start from an imitation of the scripted user ``imitate``: a
    registered scripted user, a new feed-forward policy (no ``init``, not ``recurrent``), the
    users of one technique (``cells``, :func:`~agents.learned.mixed_env.training_cells`: one
    population or a mix of them, since the scripted user is built for one technique's body)
    stepped in this process.

    Raises:
        ValueError: naming what stands in the way (an unknown name lists the scripted users).
    """
    from agents.scripted import POLICIES

    if imitate not in POLICIES:
        raise ValueError(
            f"imitate={imitate!r}: not a scripted user; choose from {', '.join(sorted(POLICIES))}"
        )
    for bad, why in (
        (init is not None, "a new policy, not init's"),
        (recurrent, "a feed-forward policy, not a recurrent one"),
        (len({str(c[0]) for c in cells}) > 1, "one technique's users, not a mix of techniques"),
        (env_workers > 1, "users stepped in this process (env_workers=1)"),
    ):
        if bad:
            raise ValueError(f"imitate={imitate!r} trains {why}")


def imitate_scripted(
    model: Any, env: Any, users: Any, name: str, steps: int, seed: int
) -> list[dict[str, float]]:
    """:func:`imitate` the scripted user ``name``, built for the users ``users``
    (:func:`scripted_teacher`), in ``env`` (``users`` as the policy sees them); the imitation's
    env streams are seeded from ``seed + 50_000``, apart from the training's. Returns
    :func:`imitate`'s rounds."""
    return imitate(model, env, scripted_teacher(name, users), steps, seed=seed + 50_000)


def scripted_teacher(name: str, users: Any, mixed_bodies: bool = False) -> Any:
    """The batched scripted user ``name`` for the vector env ``users``: its observation layout
    and its body (:func:`agents.scripted.params_from_env`).

    ``users`` may be a mix (:class:`~agents.learned.mixed_env.MixedUsersEnv`): the scripted user
    reads the mix's layout, the richest part's, into which every part's observation is read (a
    part without ``head_on_torso`` reads 0 there, its head straight on the torso). Where the
    parts share one body (a mix of populations) one scripted user acts for all; where they do
    not (a mix of techniques: their step lengths, stop distances and ways of placing the map
    differ), ``mixed_bodies`` gives :class:`BodyTeachers`, one scripted user per body acting for
    its parts' users.

    Raises:
        ValueError: a mix whose parts' bodies differ, without ``mixed_bodies``.
    """
    from agents.scripted import ObservationLayout, make_policy, params_from_env

    parts = getattr(users, "parts", None)
    if parts is None:
        return make_policy(name, ObservationLayout.from_env(users), params_from_env(users))
    layout = ObservationLayout.from_env(parts[users.richest])
    bodies = [params_from_env(p) for p in parts]
    if all(b == bodies[0] for b in bodies[1:]):
        return make_policy(name, layout, bodies[0])
    if not mixed_bodies:
        raise ValueError(
            f"imitate={name!r}: the mix's parts ({', '.join(users.cells)}) have different "
            "bodies; a scripted user acts for one"
        )
    distinct: list[Any] = []
    for b in bodies:
        if b not in distinct:
            distinct.append(b)
    bounds = np.cumsum([0, *(p.num_envs for p in parts)])
    rows = [
        np.concatenate(
            [np.arange(bounds[i], bounds[i + 1]) for i, b in enumerate(bodies) if b == body]
        )
        for body in distinct
    ]
    return BodyTeachers([make_policy(name, layout, body) for body in distinct], rows)


class BodyTeachers:
    """Scripted users of one kind with different bodies, each acting for its own users of one
    batch (:func:`scripted_teacher` of a mix of techniques): ``act`` hands each its rows and
    puts its actions back in place; ``reset`` starts the episodes of the rows given.

    Args:
        policies: one batched scripted user per body.
        rows: the batch rows each acts for (together, every row once).
    """

    def __init__(self, policies: list[Any], rows: list[NDArray[np.intp]]) -> None:
        every = np.sort(np.concatenate(rows))
        if not np.array_equal(every, np.arange(every.size)):
            raise ValueError("BodyTeachers: the rows must cover the batch, each row once")
        self.policies, self.rows = policies, [np.asarray(r, np.intp) for r in rows]
        self._owner = np.empty(every.size, np.intp)  # row -> (policy, its place there)
        self._place = np.empty(every.size, np.intp)
        for k, r in enumerate(self.rows):
            self._owner[r], self._place[r] = k, np.arange(r.size)

    def act(self, obs: Any) -> NDArray[np.float32]:
        """Each row's action from the scripted user of its body, (B, 5)."""
        obs = np.asarray(obs)
        out = np.empty((obs.shape[0], ACTION_SIZE), np.float32)
        for policy, r in zip(self.policies, self.rows, strict=True):
            out[r] = policy.act(obs[r])
        return out

    def reset(self, rng: Any = None, rows: Any = None) -> None:
        """Start the episodes of ``rows`` (batch indices; None: every row)."""
        if rows is None:
            for policy in self.policies:
                policy.reset()
            return
        rows = np.asarray(rows, np.intp)
        for k, policy in enumerate(self.policies):
            mine = self._place[rows[self._owner[rows] == k]]
            if mine.size:
                policy.reset(rows=mine)


def _batches(n: int, batch_size: int, rng: np.random.Generator):
    order = rng.permutation(n)
    for start in range(0, n, batch_size):
        yield order[start : start + batch_size]


def _fit_policy(policy, optimiser, seen, labels, epochs, batch_size, rng) -> float:
    """The policy's Gaussian fitted to the labels by maximum likelihood: its mean by least
    squares, then each action's log standard deviation set to that of the mean's residuals (the
    likelihood's maximum for the fitted mean; no lower than :data:`MIN_LOG_STD`). Returns the
    mean negative log-likelihood of the labels per sample."""
    import torch

    obs = torch.as_tensor(np.concatenate(seen), device=policy.device)
    act = torch.as_tensor(np.concatenate(labels), device=policy.device)
    policy.set_training_mode(True)
    for _ in range(epochs):
        for rows in _batches(len(obs), batch_size, rng):
            idx = torch.as_tensor(rows, device=policy.device)
            loss = torch.nn.functional.mse_loss(_mean_action(policy, obs[idx]), act[idx])
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
    policy.set_training_mode(False)
    with torch.no_grad():
        residual = torch.cat(
            [
                _mean_action(policy, obs[i : i + 65536]) - act[i : i + 65536]
                for i in range(0, len(obs), 65536)
            ]
        )
        log_std = 0.5 * torch.log(residual.pow(2).mean(0) + 1e-12)
        policy.log_std.copy_(log_std.clamp(min=MIN_LOG_STD))
        std = policy.log_std.exp()
        nll = 0.5 * (residual / std).pow(2) + policy.log_std + 0.5 * np.log(2 * np.pi)
    return float(nll.sum(1).mean())


def _mean_action(policy, obs):
    """The policy's Gaussian mean for ``obs`` (a tensor), with gradients."""
    features = policy.extract_features(obs, policy.pi_features_extractor)
    return policy.action_net(policy.mlp_extractor.forward_actor(features))


def episode_returns(
    rewards: np.ndarray, ends: np.ndarray, gamma: float
) -> tuple[np.ndarray, np.ndarray]:
    """Each step's discounted return to the end of its episode, from a ``(T, B)`` block of
    rewards and episode ends (a step's end: its episode finished with it).

    Returns:
        ``(returns, known)``, both ``(T, B)``: ``known`` is False where the step's episode runs
        past the block (its return is not known; ``returns`` holds the part within the block).
    """
    steps, n_envs = rewards.shape
    returns = np.zeros((steps, n_envs))
    known = np.zeros((steps, n_envs), bool)
    g = np.zeros(n_envs)
    ended = np.zeros(n_envs, bool)
    for t in range(steps - 1, -1, -1):
        g = rewards[t] + gamma * np.where(ends[t], 0.0, g)
        ended |= ends[t]
        returns[t], known[t] = g, ended
    return returns, known


def _fit_values(policy, optimiser, obs, rewards, ends, gamma, epochs, batch_size, rng) -> None:
    """Fit the value function to the discounted returns of the episodes that ended in ``obs``'s
    round (:func:`episode_returns`; the others are left out)."""
    import torch

    returns, known = episode_returns(rewards, ends, gamma)
    if not known.any():
        return
    x = torch.as_tensor(obs[known], device=policy.device)
    y = torch.as_tensor(returns[known], dtype=torch.float32, device=policy.device)
    policy.set_training_mode(True)
    for _ in range(epochs):
        for rows in _batches(len(x), batch_size, rng):
            idx = torch.as_tensor(rows, device=policy.device)
            loss = torch.nn.functional.mse_loss(policy.predict_values(x[idx]).flatten(), y[idx])
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
    policy.set_training_mode(False)
