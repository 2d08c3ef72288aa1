"""vrloco_env: the simulated hands-free VR user, its sensors, and the Gymnasium environment.

Data flows one way: :mod:`vrloco_env.user.motion` (intent -> true head, skeleton, steps) ->
:mod:`vrloco_env.sensors` (head IMU, Kinect v2, head camera) -> :mod:`estimators` (the stages a
technique names: :mod:`vrloco_env.techniques`, :mod:`vrloco_env.pipeline`) -> locomotion (or
:mod:`vrloco_env.head_tracking` for real walking) -> the world (:mod:`vrloco_env.world`,
:mod:`vrloco_env.world.sim`, the task: :mod:`vrloco_env.tasks`) -> observation
(:mod:`vrloco_env.observation`, :mod:`vrloco_env.core`).

Importing the package registers one id per registered task, ``VRLoco-Approach-v0``,
``VRLoco-Avoid-v0`` and ``VRLoco-Interact-v0`` (:func:`vrloco_env.tasks.register_task` adds
more)::

    import gymnasium as gym
    env = gym.make("vrloco_env:VRLoco-Approach-v0")
"""

import estimators  # noqa: F401  (first: numba's cache folder, estimators.numba_cache)
from vrloco_env.registration import ENV_IDS, register_envs

__version__ = "0.1.0"
__all__ = ["ENV_IDS", "__version__", "register_envs"]

register_envs()
