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

#: name -> the Task subclass, or "module:attr" naming it (imported on first use).
TASKS: dict[str, Any] = {}


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
    TASKS[name] = task
    from vrloco_env.registration import register_id

    register_id(env_id(name), name)


def _is_task(obj: Any) -> bool:
    from vrloco_env.tasks.base import Task

    return isinstance(obj, type) and issubclass(obj, Task)


def __getattr__(name: str) -> Any:  # Task and NoConfig, imported when first asked for
    if name in ("Task", "NoConfig"):
        from vrloco_env.tasks import base

        return getattr(base, name)
    raise AttributeError(f"module 'vrloco_env.tasks' has no attribute {name!r}")


def task_names() -> list[str]:
    """The registered task names, in registration order."""
    return list(TASKS)


def get_task(name: str) -> type[Task]:
    """The Task subclass registered as ``name`` (a ValueError listing the names otherwise)."""
    if name not in TASKS:
        raise ValueError(f"task={name!r}: must be one of {', '.join(TASKS)}")
    target = TASKS[name]
    if isinstance(target, str):
        from estimators.registry import load_attr

        target = load_attr(target, "task")
        if not _is_task(target):
            raise TypeError(f"task {name!r}: {TASKS[name]!r} is not a Task subclass")
        TASKS[name] = target
    return target


def make_layout(task: str, room: Any, rng: Any, task_config: Any = None) -> Any:
    """A room of task ``task`` (:meth:`Task.draw_layout`) from ``room`` (a
    :class:`~vrloco_env.world.config.RoomConfig`) and the generator ``rng``."""
    return get_task(task)(1, 0.1, task_config).draw_layout(room, rng)


register_task("approach", "vrloco_env.tasks.approach:Approach")
register_task("avoid", "vrloco_env.tasks.avoid:Avoid")
register_task("interact", "vrloco_env.tasks.interact:Interact")
register_task("doorway", "vrloco_env.tasks.doorway:Doorway")
register_task("reach", "vrloco_env.tasks.reach:Reach")
