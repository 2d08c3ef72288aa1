"""Offline-RL datasets of the benchmark's simulated users, in Minari's format (``vrloco record``).

:func:`record_dataset` plays seeded episodes of a policy as the benchmark plays a cell's episode
alone in a single env (:func:`agents.benchmark.episodes.run_episode`: episode ``i`` is
``reset(seed=seed + i)``, the policy's randomness ``default_rng([seed + i, 1])``) on
``gym.make(env_id(task), technique=..., population=...)`` and writes them as a Minari dataset
(``minari.load_dataset(dataset_id)`` reads it; Minari's root folder is ``MINARI_DATASETS_PATH``,
else ``~/.minari/datasets``). An episode of ``T`` control steps holds, in Minari's layout:

* ``observations`` ``(T + 1, n)`` float32: the reset's, then each step's;
* ``actions`` ``(T, 5)`` float32: the actions the env applied (the policy's, in the action
  space's dtype, clipped to [-1, 1] as the env clips them);
* ``rewards``, ``terminations``, ``truncations`` ``(T,)``;
* ``infos``: every key of the env's step ``info`` whose value is a number or flag of one shape
  throughout (every key :mod:`agents.benchmark.metrics` and :mod:`agents.benchmark.wip_measures`
  read among them), ``(T + 1, ...)`` each: row 0 is the reset's ``info`` (for a key it does not
  report: NaN for floats, 0 for integers, False for flags), rows 1 to T the steps';
* its seed in the episode's metadata (``dataset.storage.get_episode_metadata``).

The dataset keeps the env's spec (id, keywords, horizon), so ``dataset.recover_environment()``
makes the same env: reset with an episode's seed and given its actions it plays the stored
observations again, bit for bit. :func:`dataset_episode_stats` gives back the benchmark's
:class:`~agents.benchmark.metrics.EpisodeStats` of the stored episodes, so that
``agents.benchmark.metrics.summarize(dataset_episode_stats(dataset))`` is the benchmark's row of the
dataset.

Minari is an optional dependency (``pip install 'vrloco[minari]'``); it writes HDF5 through h5py.
"""

from __future__ import annotations

import shutil
import warnings
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from agents.benchmark.metrics import STEP_KEYS, EpisodeStats, episode_stats

__all__ = [
    "INSTALL_HINT",
    "LAST_KEYS",
    "MinariMissing",
    "dataset_episode_stats",
    "dataset_path",
    "record_dataset",
]

INSTALL_HINT = "pip install 'vrloco[minari]' (in a checkout: pip install -e '.[minari]')"

#: The ``info`` keys the benchmark reads at an episode's last step (besides :data:`STEP_KEYS`).
LAST_KEYS = ("is_success", "collisions", "elapsed_time", "walked")


class MinariMissing(RuntimeError):
    """Minari is not installed (the message says how to install it)."""


def _minari() -> Any:
    """The ``minari`` module, or :class:`MinariMissing` with the install command."""
    try:
        import minari
    except ImportError:
        raise MinariMissing(f"Minari is not installed: {INSTALL_HINT}") from None
    return minari


def dataset_path(dataset_id: str) -> Path:
    """The folder of Minari dataset ``dataset_id`` (under ``MINARI_DATASETS_PATH``, else
    ``~/.minari/datasets``), whether or not it exists.

    Raises:
        ValueError: ``dataset_id`` is not a Minari dataset id, ``(namespace/)name-v<version>``.
        MinariMissing: Minari is not installed.
    """
    _minari()
    from minari.dataset.minari_dataset import parse_dataset_id
    from minari.storage import get_dataset_path

    try:
        ok = isinstance(dataset_id, str) and parse_dataset_id(dataset_id)[2] is not None
    except (ValueError, TypeError):  # no match; or no version (Minari's parser fails on it)
        ok = False
    if not ok:
        raise ValueError(
            f"minari dataset id {dataset_id!r}: must be (namespace/)name-v<version>, letters, "
            "digits, '_' and '-' (e.g. vrloco/approach-goal_seeker-v0)"
        )
    return Path(get_dataset_path(dataset_id))


class _Tape(gym.Wrapper):
    """Records what an env is given and gives back, episode after episode (see
    :func:`record_dataset`). The action passed on is the one recorded: the policy's in the action
    space's dtype, clipped to its bounds. The dataset takes the spec of the env it wraps (this
    wrapper is not part of the env that ``recover_environment`` makes)."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.episodes: list[dict[str, Any]] = []

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[Any, dict]:
        obs, info = self.env.reset(seed=seed, options=options)
        self.episodes.append(
            {
                "seed": seed,
                "observations": [np.array(obs)],
                "actions": [],
                "rewards": [],
                "terminations": [],
                "truncations": [],
                "infos": [_copy(info)],
            }
        )
        return obs, info

    def step(self, action: Any) -> tuple[Any, Any, bool, bool, dict]:
        from vrloco_env.actions import check_action

        space = self.action_space
        applied = np.minimum(
            np.maximum(check_action(action).astype(space.dtype), space.low), space.high
        )
        obs, reward, terminated, truncated, info = self.env.step(applied)
        ep = self.episodes[-1]
        ep["observations"].append(np.array(obs))
        ep["actions"].append(applied)
        ep["rewards"].append(float(reward))
        ep["terminations"].append(bool(terminated))
        ep["truncations"].append(bool(truncated))
        ep["infos"].append(_copy(info))
        return obs, reward, terminated, truncated, info


def _copy(info: dict) -> dict:
    """``info`` with its arrays copied (an env may reuse its buffers)."""
    return {k: np.array(v) if isinstance(v, np.ndarray) else v for k, v in info.items()}


def _numeric(value: Any) -> NDArray | None:
    """``value`` as an array of numbers or flags, None where it is none."""
    if value is None or isinstance(value, dict | str | bytes):
        return None
    try:
        a = np.asarray(value)
    except (ValueError, TypeError):  # ragged
        return None
    return a if a.dtype.kind in "biuf" else None


def _info_columns(episodes: list[dict]) -> dict[str, tuple[np.dtype, tuple[int, ...]]]:
    """The step ``info`` keys that hold numbers or flags of one dtype and shape at every step of
    every episode, with that dtype and shape."""
    first = episodes[0]["infos"][1]
    columns = {}
    for key, value in first.items():
        a = _numeric(value)
        if a is None:
            continue
        same = all(
            (b := _numeric(info.get(key))) is not None and b.dtype == a.dtype and b.shape == a.shape
            for ep in episodes
            for info in ep["infos"][1:]
        )
        if same:
            columns[key] = (a.dtype, a.shape)
    return columns


def _info_arrays(infos: list[dict], columns: dict) -> dict[str, NDArray]:
    """One episode's ``infos`` (the reset's, then the steps'), stacked per key of ``columns``;
    row 0 holds the reset's value where it reports the key with that shape, else NaN, 0 or
    False."""
    out = {}
    for key, (dtype, shape) in columns.items():
        r = _numeric(infos[0].get(key))
        if r is not None and r.shape == shape and np.can_cast(r.dtype, dtype, "same_kind"):
            first = r.astype(dtype)
        else:
            first = np.full(shape, np.nan if dtype.kind == "f" else 0, dtype=dtype)
        out[key] = np.stack([first, *(np.asarray(info[key]) for info in infos[1:])])
    return out


def _buffers(episodes: list[dict], first_id: int = 0) -> list[Any]:
    """Minari's episode buffers of the recorded ``episodes``."""
    from minari.data_collector import EpisodeBuffer

    columns = _info_columns(episodes)
    return [
        EpisodeBuffer(
            id=first_id + i,
            seed=ep["seed"],
            observations=np.stack(ep["observations"]),
            actions=np.stack(ep["actions"]),
            rewards=np.asarray(ep["rewards"], dtype=np.float64),
            terminations=np.asarray(ep["terminations"], dtype=bool),
            truncations=np.asarray(ep["truncations"], dtype=bool),
            infos=_info_arrays(ep["infos"], columns),
        )
        for i, ep in enumerate(episodes)
    ]


def _replaceable(path: Path) -> bool:
    """Whether ``path`` is a dataset's folder that ``force`` may remove: one holding Minari's
    ``data`` folder and nothing else (not a namespace of other datasets)."""
    return path.is_dir() and all(p.name == "data" for p in path.iterdir())


def _check_free(dataset_id: str, path: Path, force: bool) -> None:
    if not path.exists():
        return
    if not force:
        raise FileExistsError(
            f"minari dataset {dataset_id!r} already exists at {path}; give --force to replace "
            "it, or another name"
        )
    if not _replaceable(path):
        raise FileExistsError(
            f"{path} (minari dataset {dataset_id!r}) holds more than a dataset (a namespace of "
            "other datasets?); not removed: choose another name"
        )


def record_dataset(
    task: str,
    policy: str,
    dataset_id: str,
    technique: str = "zhang2021",
    episodes: int = 100,
    seed: int = 0,
    max_episode_steps: int | None = None,
    force: bool = False,
    progress: bool = False,
) -> Any:
    """Play ``episodes`` seeded episodes of ``policy`` and write them as Minari dataset
    ``dataset_id`` (see the module docstring).

    Args:
        task: a registered task (:mod:`vrloco_env.tasks`).
        policy: a policy spec (:mod:`agents.benchmark.policies`: a scripted user, a PPO ``.zip`` or
            ``module:attr``, optionally ``+<population>``, whose head behaviour the env takes).
        dataset_id: Minari's ``(namespace/)name-v<version>``.
        technique: a registered technique's name or ``"module:attr"`` naming one (a name: the
            dataset's env spec stores it).
        episodes: episodes, >= 1; episode ``i`` is seeded ``seed + i``.
        seed: the first episode's seed, >= 0.
        max_episode_steps: the env's horizon in control steps (``gym.make``'s argument; None:
            the env's own).
        force: replace an existing dataset of that id (only once the new episodes are played).
        progress: show a progress bar over the episodes.

    Returns:
        The written :class:`minari.MinariDataset`.

    Raises:
        ValueError: an unknown task, policy or technique, a bad count, seed or id (one line).
        FileExistsError: the dataset exists and ``force`` is False.
        MinariMissing: Minari is not installed.
    """
    from agents.benchmark.episodes import run_episode
    from agents.benchmark.policies import build_policy, check_policy, env_population
    from vrloco_env import __version__
    from vrloco_env.tasks import env_id, get_task
    from vrloco_env.techniques import get_technique

    minari = _minari()
    get_task(task)
    check_policy(policy)
    if not isinstance(technique, str):
        raise ValueError(
            f"technique={technique!r}: give a registered name or 'module:attr' (the dataset's "
            "env spec stores it as text)"
        )
    get_technique(technique)
    for name, value, lo in (
        ("episodes", episodes, 1),
        ("seed", seed, 0),
        ("max_episode_steps", max_episode_steps, 1),
    ):
        if value is None and name == "max_episode_steps":
            continue
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < lo:
            raise ValueError(f"{name}={value!r}: must be an integer >= {lo}")
    path = dataset_path(dataset_id)
    _check_free(dataset_id, path, force)

    import vrloco_env  # noqa: F401  (registers the ids)

    population = env_population(policy)
    limit = {} if max_episode_steps is None else {"max_episode_steps": int(max_episode_steps)}
    env = _Tape(gym.make(env_id(task), technique=technique, population=population, **limit))
    try:
        pol = build_policy(policy, env)
        seeds = range(int(seed), int(seed) + int(episodes))
        if progress:
            from tqdm import tqdm

            seeds = tqdm(seeds, desc=f"record {policy} on {env_id(task)}", unit="episode")
        for s in seeds:
            run_episode(env, pol, s, name=policy)
        _check_free(dataset_id, path, force)  # another process may have written it meanwhile
        if path.exists():
            shutil.rmtree(path)
        description = (
            f"vrloco record: {episodes} episodes of policy {policy!r} on {env_id(task)} "
            f"(technique {technique!r}, population {population!r}), seeds {seed} to "
            f"{seed + episodes - 1} (policy randomness default_rng([seed, 1])). infos: the env's "
            "step info keys; row 0 is the reset's info (NaN, 0 or False where it reports none)."
        )
        try:
            with warnings.catch_warnings():  # Minari's reminders of the fields left out
                warnings.filterwarnings("ignore", message=r"`\w+` is set to None")
                return minari.create_dataset_from_buffers(
                    dataset_id,
                    _buffers(env.episodes),
                    env=env.env,
                    algorithm_name=policy,
                    description=description,
                    requirements=[f"vrloco=={__version__}"],
                    data_format="hdf5",
                )
        except BaseException:  # a full disk, Ctrl-C: no half-written dataset left behind
            shutil.rmtree(path, ignore_errors=True)
            raise
    finally:
        env.close()


def dataset_episode_stats(dataset: Any) -> list[EpisodeStats]:
    """The benchmark's :class:`~agents.benchmark.metrics.EpisodeStats` of every episode of
    ``dataset`` (a :class:`minari.MinariDataset` written by :func:`record_dataset`), from its
    ``infos`` and seeds alone, as :func:`agents.benchmark.episodes.run_episode` gives them.

    Raises:
        ValueError: an episode's ``infos`` lack a key the metrics read (named).
    """
    needed = (*STEP_KEYS, *LAST_KEYS, "shortest_path", "position")
    metadata = list(dataset.storage.get_episode_metadata(dataset.episode_indices))
    out = []
    for ep, meta in zip(dataset.iterate_episodes(), metadata, strict=True):
        infos = ep.infos or {}
        missing = [k for k in needed if k not in infos]
        if missing:
            raise ValueError(
                f"episode {ep.id} of the dataset has no infos {', '.join(missing)} (the "
                "benchmark's metrics read them; vrloco record stores them)"
            )
        steps = {k: infos[k][1:] for k in STEP_KEYS}
        last = {k: infos[k][-1] for k in LAST_KEYS}
        if meta.get("seed") is None:
            raise ValueError(f"episode {ep.id} of the dataset has no seed in its metadata")
        out.append(
            episode_stats(
                meta["seed"],
                float(infos["shortest_path"][0]),
                steps,
                last,
                start_position=infos["position"][0],
            )
        )
    return out
