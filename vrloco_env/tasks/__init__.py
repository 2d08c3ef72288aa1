"""The tasks: one file per task, one registry that generates the Gymnasium ids, the benchmark's
choices and the command line's help.

* ``approach`` (:mod:`vrloco_env.tasks.approach`) — reach the goal in a room with obstacles.
* ``avoid`` (:mod:`vrloco_env.tasks.avoid`) — Zhang 2021's Fig. 5 corridor, collision-free.
* ``interact`` (:mod:`vrloco_env.tasks.interact`) — reach a pedestal, hold a hand orientation.
* ``doorway`` (:mod:`vrloco_env.tasks.doorway`) — pass a sequence of doorways 0.8-1.2 m wide,
  collision-free.
* ``reach`` (:mod:`vrloco_env.tasks.reach`) — stop 0.3-0.8 m from a pedestal without touching it
  and hold a hand orientation there.

A new task is a :class:`~vrloco_env.tasks.base.Task` subclass in a file of its own plus one
:func:`register_task` line (``register_task("dual_goal", "mypkg.dual_goal:DualGoal")``), which
makes ``gym.make("VRLoco-DualGoal-v0")``, ``gym.make_vec`` and ``vrloco benchmark --tasks
dual_goal`` work. Registered targets are imported when first used, so ``import vrloco_env``
stays light.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from estimators.registry import Registry

if TYPE_CHECKING:
    from vrloco_env.tasks.base import Task

__all__ = [
    "TASKS",
    "NoConfig",
    "Task",
    "env_id",
    "get_task",
    "make_layout",
    "register_task",
    "task_names",
]


def _is_task(obj: Any) -> bool:
    from vrloco_env.tasks.base import Task

    return isinstance(obj, type) and issubclass(obj, Task)


def _loaded_task(obj: Any, name: str, target: str) -> Any:
    """The Task subclass a registered ``"module:attr"`` named (a TypeError otherwise)."""
    if not _is_task(obj):
        raise TypeError(f"task {name!r}: {target!r} is not a Task subclass")
    return obj


#: name -> the Task subclass; one registered as "module:attr" is imported on first use.
TASKS: Registry[type[Task]] = Registry("task", load=_loaded_task)


def env_id(name: str) -> str:
    """The Gymnasium id of task ``name``: ``VRLoco-<Name>-v0`` (``dual_goal`` -> DualGoal)."""
    return "VRLoco-" + "".join(part.capitalize() for part in name.split("_")) + "-v0"


def register_task(name: str, task: Any) -> None:
    """Register ``task`` (a Task subclass, or ``"module:attr"`` naming one) under ``name`` and
    its Gymnasium id (:func:`env_id`); registering a name again replaces it."""
    if not isinstance(name, str) or not name.isidentifier():
        raise ValueError(f"task name {name!r} must be an identifier (letters, digits, _)")
    if not isinstance(task, str) and not _is_task(task):
        raise TypeError(f"task must be a Task subclass or 'module:attr', got {task!r}")
    TASKS.register(name, task)
    from vrloco_env.registration import register_id

    register_id(env_id(name), name)


def __getattr__(name: str) -> Any:  # Task and NoConfig, imported when first asked for
    if name in ("Task", "NoConfig"):
        from vrloco_env.tasks import base

        return getattr(base, name)
    raise AttributeError(f"module 'vrloco_env.tasks' has no attribute {name!r}")


def task_names() -> list[str]:
    """The registered task names, in registration order."""
    return TASKS.names()


def get_task(name: str) -> type[Task]:
    """The Task subclass registered as ``name`` (a ValueError listing the names otherwise)."""
    return TASKS.get(name)


def make_layout(task: str, room: Any, rng: Any, task_config: Any = None) -> Any:
    """A room of task ``task`` (:meth:`Task.draw_layout`) from ``room`` (a
    :class:`~vrloco_env.world.config.RoomConfig`) and the generator ``rng``."""
    return get_task(task)(1, 0.1, task_config).draw_layout(room, rng)


register_task("approach", "vrloco_env.tasks.approach:Approach")
register_task("avoid", "vrloco_env.tasks.avoid:Avoid")
register_task("interact", "vrloco_env.tasks.interact:Interact")
register_task("doorway", "vrloco_env.tasks.doorway:Doorway")
register_task("reach", "vrloco_env.tasks.reach:Reach")
