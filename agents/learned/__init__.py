"""Learned simulated users: stable-baselines3 PPO on the native vector env.

``vrloco train --task approach --steps 2000000`` trains PPO on
:class:`~vrloco_env.vector.VRLocoVectorEnv` (all users batched in one process), with a progress
bar, TensorBoard logs, periodic checkpoints and an evaluation callback on separately seeded
episodes (:mod:`agents.learned.train`); ``vrloco evaluate MODEL`` runs a trained policy through
the benchmark's metrics (:mod:`agents.learned.evaluate`). ``vrloco train --seeds 0,1,2``
(:func:`~agents.learned.seeds.train_seeds`) trains one run per seed in parallel worker processes
(``--backend ray``: as Ray tasks on a Ray cluster) and draws their curves together, with the mean
and the spread over the seeds (:mod:`agents.learned.curves`). RLlib's PPO is in
:mod:`agents.learned.rllib`; a policy's episodes as a Minari dataset in
:mod:`agents.learned.offline_datasets`.

A run trains on one benchmark cell: a task, a technique (:mod:`vrloco_env.techniques`), a user
population (:mod:`vrloco_env.user.population`, its head behaviour in the env) and a physical-room
condition (:mod:`agents.benchmark.conditions`); the cell is saved with the model
(``model.vrloco_cell``) beside the env's settings (``model.vrloco_env``), and so is how the policy
sees the env (``model.vrloco_policy``: ``frame_stack``, the last k observations side by side
through :class:`~vrloco_env.wrappers.FrameStack`, ``recurrent``, sb3-contrib's
``RecurrentPPO`` with an LSTM policy, and ``residual_on``, the scripted user whose actions the
policy corrects; :mod:`agents.learned.models`), so that
:func:`~agents.learned.evaluate.evaluate_model` and the benchmark
(:class:`agents.benchmark.policies.LearnedPolicy`) play it on its own cell, the way it was trained.
A run may train on a mix instead (``--technique zhang2021,smooth`` or ``all``, ``--population
idealised,typical --variability none,typical``): every technique with every population, the
users shared between the cells in one batch (:class:`~agents.learned.mixed_env.MixedUsersEnv`);
the model's cell then lists them, and it plays any of them as its own. A new policy may first
imitate a scripted user (``--imitate goal_seeker``, :func:`~agents.learned.imitation.imitate`:
DAgger, the policy's Gaussian and critic fitted to the scripted user's actions and returns)
before PPO goes on from it; or it may learn a correction of a scripted user's actions
(``--residual-on goal_seeker``, :mod:`agents.learned.residual`), starting as that user.

Speed. The env's compiled kernels and torch both run OpenMP thread pools on the same cores.
This package imports :mod:`estimators.kernels` before torch (:mod:`agents.learned.threads`, the
first module it imports), so that torch's OpenMP runtime starts with the passive wait policy that
module sets (``OMP_WAIT_POLICY=PASSIVE``: idle threads sleep instead of spinning on the cores the
other pool needs), and PPO runs its rollouts and updates on one torch thread
(:class:`~agents.learned.train.OneTorchThread`: the forward pass of one step's users is too small
to share out, and the update's small minibatches run faster on one thread than on two that sleep
between parallel regions). ``benchmarks/bench_training.py`` times the loop against the default
settings and checks that it trains the weights the default loop trains on one thread. A process
that imported torch before this package (without ``OMP_WAIT_POLICY`` set) keeps torch's spinning
threads; :func:`~agents.learned.train.train_ppo` warns.

:class:`~agents.learned.train.SB3VecEnv` adapts the Gymnasium vector env to stable-baselines3's
``VecEnv`` interface. Both autoreset in the same step, so the adapter only reshapes: the finished
episode's last observation goes to ``infos[i]["terminal_observation"]`` and a time-limit end sets
``infos[i]["TimeLimit.truncated"]``, which PPO uses to bootstrap the value of truncated episodes.
"""

from agents.learned import threads  # noqa: F401  (first: before any module imports torch)

# isort: split
from typing import Any

#: name -> module of this package's public API, imported on first use (so that importing a
#: light sub-package, :mod:`agents.learned.users`, does not import torch).
_PUBLIC = {
    "evaluate_model": "agents.learned.evaluate",
    "CELL_KEYS": "agents.learned.models",
    "env_settings": "agents.learned.models",
    "model_cell": "agents.learned.models",
    "model_env_settings": "agents.learned.models",
    "model_policy": "agents.learned.models",
    "OneTorchThread": "agents.learned.train",
    "SB3VecEnv": "agents.learned.train",
    "make_model": "agents.learned.train",
    "train_ppo": "agents.learned.train",
    "train_seeds": "agents.learned.seeds",
}


def __getattr__(name: str) -> Any:
    if name not in _PUBLIC:
        raise AttributeError(f"module 'agents.learned' has no attribute {name!r}")
    import importlib

    return getattr(importlib.import_module(_PUBLIC[name]), name)


__all__ = [
    "CELL_KEYS",
    "OneTorchThread",
    "SB3VecEnv",
    "env_settings",
    "evaluate_model",
    "make_model",
    "model_cell",
    "model_env_settings",
    "model_policy",
    "train_ppo",
    "train_seeds",
]
