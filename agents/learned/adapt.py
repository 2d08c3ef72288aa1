"""Technique-adapted users: the shipped learned user of a task, fine-tuned on one cell.

A person who learns that a technique stops late stops earlier; a shipped learned user
(:mod:`agents.learned.users`) does the same after :func:`adapted_user` trains a copy of it on the
cell (task, technique, population, condition) for ``steps`` more environment steps, with the PPO
settings and the training objective it was trained with, seeded, reading the cell's observation
as it was trained to (its fields by name), and with the human variability of the population the
benchmark plays it with (``ppo@STEPS+typical``). Every technique gets the same
budget, and the fine-tuning runs on one torch thread as :func:`~agents.learned.train.train_ppo`
does, so that an adapted user's weights do not depend on the machine's core count. The result
is cached in ``cache_dir`` under a key of the cell, the shipped model's bytes,
the package's source fingerprint (:func:`agents.benchmark.resume.source_fingerprint`), the budget
and the seed, so a rerun reuses it; a cached file that does not load is reported and trained
again, never reused. ``steps = 0`` is the shipped user itself.

In the benchmark: ``vrloco benchmark --policies ppo --adapt STEPS`` (the policy spec
``ppo@STEPS``, :mod:`agents.benchmark.policies`) adapts the user to every cell before the run.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any

__all__ = ["DEFAULT_CACHE", "adapted_user", "cache_key"]


#: Where adapted users are kept unless told otherwise (``VRLOCO_ADAPT_CACHE`` overrides it).
DEFAULT_CACHE = Path(
    os.environ.get("VRLOCO_ADAPT_CACHE", Path.home() / ".cache" / "vrloco" / "adapted")
)


def cache_key(cell: dict[str, Any], shipped: Path, steps: int, seed: int) -> str:
    """The cache key (hex) of an adapted user: its cell, the shipped model's bytes, the source
    fingerprint, the budget and the seed."""
    from agents.benchmark.resume import source_fingerprint

    text = json.dumps(
        {
            "cell": cell,
            "shipped": hashlib.sha256(Path(shipped).read_bytes()).hexdigest(),
            "source": source_fingerprint(),
            "steps": int(steps),
            "seed": int(seed),
        },
        sort_keys=True,
    )
    return hashlib.sha256(text.encode()).hexdigest()[:24]


def adapted_user(
    task: str,
    technique: Any = None,
    population: Any = None,
    condition: str | None = None,
    steps: int = 0,
    seed: int = 0,
    cache_dir: Path | None = None,
    num_envs: int = 32,
    variability: str | None = None,
) -> Path:
    """The model file of the shipped ``task`` user adapted to the cell for ``steps`` steps,
    with the human variability of the population ``variability`` around it while it trains (as
    the benchmark plays ``ppo@STEPS+<population>``; None: none).

    Raises:
        ValueError: no shipped user for ``task``, ``steps`` not an integer >= 0, or a cell the
            registries do not know (their errors).
    """
    from agents.benchmark.policies import load_ppo
    from agents.learned.models import (
        ModelFields,
        cell_of,
        env_settings,
        model_policy,
        observation_columns,
    )
    from agents.learned.train import OneTorchThread, SB3VecEnv, _wrap, rollout_steps
    from agents.learned.users import shipped_user
    from vrloco_env.vector import VRLocoVectorEnv

    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 0:
        raise ValueError(f"steps={steps!r}: must be an integer >= 0 (0: no adaptation)")
    shipped = shipped_user(task).path
    if steps == 0:
        return shipped
    base = load_ppo(shipped)
    reward = base.vrloco_env.get("reward")
    settings = env_settings(task, None, technique, population, condition, reward=reward)
    cell = {**cell_of(settings, technique), "variability": variability}
    folder = DEFAULT_CACHE if cache_dir is None else Path(cache_dir)
    target = folder / f"{task}_{cache_key(cell, shipped, steps, seed)}.zip"
    if target.is_file():
        try:
            load_ppo(target)
            return target
        except ValueError as err:
            print(f"adapted user {target} is damaged ({err}); training it again")
            target.unlink()
    seen = model_policy(base)
    users = VRLocoVectorEnv(num_envs, **settings)
    learner: Any = users
    if variability is not None:  # the person acts: what they see is late, what they do varies
        from agents.learned.variability_env import HumanVariabilityEnv

        learner = HumanVariabilityEnv(learner, variability, seed)
    spec = users.observation_spec
    if seen["residual_on"] is not None:  # the scripted user it corrects, built for this cell
        from agents.learned.imitation import scripted_teacher
        from agents.learned.residual import ScriptedPlusCorrection

        name = seen["residual_on"]
        learner = ScriptedPlusCorrection(learner, scripted_teacher(name, users), name, spec)
        spec = learner.observation_spec
    saved = getattr(base, "vrloco_observation", None)
    try:  # the cell's observation as the model reads it (its fields by name)
        columns = observation_columns(saved, spec)
    except ValueError as err:
        users.close()
        raise ValueError(
            f"the shipped {task} user cannot read the cell's observation: {err}"
        ) from None
    learner = learner if columns is None else ModelFields(learner, columns)
    venv = SB3VecEnv(_wrap(learner, seen["frame_stack"]), seed=seed)
    model = type(base).load(shipped, env=venv)
    model.set_random_seed(seed)
    budget = rollout_steps(steps, model.n_steps, num_envs)
    one_thread = OneTorchThread()  # the same weights on any machine (the update's sums)
    try:
        model.learn(budget, callback=one_thread, reset_num_timesteps=False, progress_bar=False)
    finally:
        one_thread.restore()
    model.vrloco_env = settings
    model.vrloco_cell = {k: v for k, v in cell.items() if k != "variability"}
    model.vrloco_variability = variability
    model.vrloco_policy = {"frame_stack": seen["frame_stack"], "residual_on": seen["residual_on"]}
    model.vrloco_observation = saved
    folder.mkdir(parents=True, exist_ok=True)
    partial = target.with_suffix(".part.zip")
    model.save(partial)
    partial.replace(target)  # whole or not at all
    venv.close()
    return target
