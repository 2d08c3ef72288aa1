"""The task pages: ``tasks/index.md`` (every task, and what the tasks share) and
``tasks/<task>.md`` (one task's id, goal, observation, action, reward, ending, configuration and
``info`` keys)."""

from __future__ import annotations

import dataclasses
import math
import re
import sys
from collections.abc import Callable
from typing import Any

from agents.reference_pages.common import PICTURE_SEED
from agents.reference_pages.docstrings import (
    _bullets,
    _doc,
    _first,
    _module_doc,
    doc_paragraphs,
    field_docs,
)
from agents.reference_pages.markdown import (
    _config_table,
    _value,
    make_page,
    md_blocks,
    md_table,
    qualname,
    to_md,
)
from agents.reference_pages.pictures import picture_layout


def _env_defaults() -> tuple[Any, Any, Any, Any]:
    """The default EnvConfig, RoomConfig, RewardConfig and MotionParams."""
    from vrloco_env.config import EnvConfig, RewardConfig
    from vrloco_env.world import RoomConfig

    env = EnvConfig()
    return env, RoomConfig(), RewardConfig(), env.motion


def _horizon() -> str:
    env, _, _, motion = _env_defaults()
    seconds = env.max_episode_steps / motion.control_rate_hz
    return f"{env.max_episode_steps} steps = {seconds:g} s at {motion.control_rate_hz:g} Hz"


def _task_text(cls: type) -> tuple[str, str]:
    """(what the user must do, the success rule) from the first paragraph of the task's module
    docstring, ``"Name: what to do (success: rule)."``; without a ``(success: ...)`` part the
    sentence itself is the rule."""
    first = _first(_module_doc(cls))
    what = first.split(": ", 1)[1] if ": " in first else first
    m = re.search(r"\s*\(success: (.*)\)\.?$", what)
    if m:
        return what[: m.start()], m.group(1)
    what = what.rstrip(".")
    return what, what


def _task_info(cls: type) -> dict[str, str]:
    """The task's ``info`` keys (from a one-user instance) with the class docstring's text on
    each (the sentence that names it, where one does)."""
    from vrloco_env.tasks.base import Task

    _, _, _, motion = _env_defaults()
    keys = sorted(cls(1, 1.0 / motion.control_rate_hz).info())
    docs = " ".join(_doc(cls).split()) + " " + " ".join(_doc(Task).split())
    found = {}
    for key in keys:
        m = re.search(rf"``{key}``(?: \(([^()]*(?:\([^()]*\)[^()]*)*)\)| (= [^.]*))?", docs)
        found[key] = to_md(m.group(1) or m.group(2)) if m and (m.group(1) or m.group(2)) else ""
        found[key] = found[key] or _INFO_NOTES.get(key, "")
    return found


#: What the task ``info`` keys that no docstring explains hold, written here from the code of
#: the tasks' ``info`` methods (a docstring's own text takes precedence).
_INFO_NOTES = {
    "dwell": "time (s) the hand has been held within tolerance in the goal region so far",
    "doorway_width_m": "width (m) of the nearest wall's doorway",
    "doorways_passed": "doorways passed so far",
}


def _observation_rows(spec: Any, source: dict[str, str]) -> list[tuple[str, ...]]:
    rows = []
    for f in spec.fields:
        sl = spec.slice(f.name)
        index = str(sl.start) if f.size == 1 else f"{sl.start}-{sl.stop - 1}"
        entries = (
            f"`{f.entries[0]}`"
            if f.size == 1
            else f"`{f.entries[0]}` ... `{f.entries[-1]}`"
            if f.size > 3
            else ", ".join(f"`{e}`" for e in f.entries)
        )
        reads = f"{f.scale:.6g} {f.unit}".strip()
        rows.append(
            (
                index,
                f"`{f.name}`",
                entries,
                f"({f.size},)",
                "float32",
                "[-1, 1]",
                reads,
                to_md(f.doc),
                source[f.name],
            )
        )
    return rows


def _observation(task_cls: type) -> list[str]:
    """The observation section of a task page."""
    from vrloco_env.observation import COMMON_FIELDS, HEAD_ON_TORSO, ObservationSpec, env_spec
    from vrloco_env.user.population import POPULATIONS

    env, _, _, motion = _env_defaults()
    task = task_cls(1, 1.0 / motion.control_rate_hz)
    spec = env_spec(env.ray_count, env.ray_range_m, task.fields())
    with_head = ObservationSpec((*spec.fields, HEAD_ON_TORSO))
    source = {name: "all tasks" for name in COMMON_FIELDS}
    source.update({f.name: f"this task (`{task_cls.__name__}.fields`)" for f in task.fields()})
    source[HEAD_ON_TORSO.name] = "a population whose head turns (below)"
    gaze = [f"`{n}`" for n, p in POPULATIONS.items() if p.gaze]
    headers = (
        "index",
        "field",
        "entries",
        "shape",
        "dtype",
        "bounds",
        "1.0 reads",
        "meaning",
        "from",
    )
    return [
        "## Observation",
        f"`Box(-1.0, 1.0, ({spec.size},), float32)` with the default `EnvConfig` "
        f"(`ray_count={env.ray_count}`, `ray_fov_deg={env.ray_fov_deg:g}`, "
        f"`ray_range_m={env.ray_range_m:g}`). Every entry is `clip(value / scale, -1, 1)` of a "
        "physical value, so the column *1.0 reads* is the value (in its unit) an entry of 1 "
        "stands for; `env.unwrapped.observation_spec.decode(obs)` gives the physical values by "
        "field (`vrloco_env.observation`). The head attitude, gait and hand are the *estimates* "
        "of the technique's stages; the goal bearing, goal distance and rays are seen from the "
        "*virtual* pose.",
        md_table(headers, _observation_rows(spec, source)),
        f"With a user population whose head turns on the torso ({', '.join(gaze)}; "
        "`population=...`, `vrloco_env.user.population`), one field is appended:",
        md_table(headers, _observation_rows(with_head, source)[-1:]),
    ]


def _action_rows() -> list[tuple[str, ...]]:
    """One row per action entry: the meaning from :mod:`vrloco_env.actions`' docstring and its
    limit from the default :class:`~vrloco_env.user.MotionParams`."""
    import vrloco_env.actions as actions

    _, _, _, motion = _env_defaults()
    bullets = _bullets(_doc(actions))
    lo, hi = motion.cadence_range_hz
    turn = math.degrees(motion.max_turn_rate)
    hand = math.degrees(motion.max_hand_rate)
    # Which MotionParams field scales each entry: actions.action_to_intent.
    limits = {
        "walk": f"cadence {lo:g}-{hi:g} steps/s (`MotionParams.cadence_range_hz`)",
        "turn": f"+-{turn:g} deg/s (`MotionParams.max_turn_rate` = "
        f"{motion.max_turn_rate:.4g} rad/s)",
    }
    rows = []
    for k, name in enumerate(actions.ACTION_NAMES):
        if name.startswith("hand_"):
            axis = name.split("_")[1]
            text = bullets["hand rates"] + f" (this entry: the {axis} axis)"
            limit = (
                f"+-{hand:g} deg/s (`MotionParams.max_hand_rate` = "
                f"{motion.max_hand_rate:.4g} rad/s)"
            )
        else:
            text, limit = bullets[name], limits[name]
        rows.append((str(k), f"`{name}`", "[-1, 1]", to_md(text), limit))
    return rows


def _action() -> list[str]:
    import vrloco_env.actions as actions

    clipping = next(p for p in doc_paragraphs(_doc(actions)) if p.startswith("Out-of-range"))
    return [
        "## Action",
        f"`Box(-1.0, 1.0, ({actions.ACTION_SIZE},), float32)`, the same for every task "
        "(`vrloco_env.actions`):",
        md_table(
            ("index", "name", "bounds", "meaning", "at 1.0 (default `MotionParams`)"),
            _action_rows(),
        ),
        to_md(clipping),
    ]


def _reward() -> list[str]:
    from vrloco_env.config import RewardConfig

    _, room, reward, _ = _env_defaults()
    docs = field_docs(RewardConfig)
    rows = [
        (f"`{f.name}`", _value(getattr(reward, f.name)), to_md(docs.get(f.name, "")))
        for f in dataclasses.fields(RewardConfig)
    ]
    return [
        "## Reward",
        to_md(_first(_doc(RewardConfig)))
        + " As `LocoCore.step` (`vrloco_env/core.py`) computes it:",
        "```text\nreward = progress * (goal distance before - goal distance after)\n"
        "       + success * [the episode succeeded this step]\n"
        "       - collision * [the step was blocked]\n"
        "       - effort * mean(action ** 2)\n"
        "       - time\n```",
        "The goal distance is the task's `goal_distance` (see *What the user must do*), in "
        "metres. A step is blocked when the avatar (radius `RoomConfig.avatar_radius` = "
        f"{room.avatar_radius:g} m), swept along the step's displacement, would touch a wall or "
        'an obstacle: the body stays, `info["collision"]` is True, `info["collisions"]` '
        'counts it and `info["cost"]` is 1 (Safety-Gymnasium style). The terms '
        "(`reward=RewardConfig(...)`), with their defaults:",
        md_table(("term", "default", "meaning"), rows),
    ]


def _ending(cls: type, rule: str) -> list[str]:
    env, _, _, _ = _env_defaults()
    free = (
        "without a single collision in the episode (`collision_free_success = True`)"
        if cls.collision_free_success
        else "collisions or not (`collision_free_success = False`)"
    )
    owner = next(b for b in cls.__mro__ if "finished" in vars(b))
    config = cls.Config()
    if owner.__name__ == "Task":
        done = "the virtual body is in the goal region, goal distance 0"
    elif hasattr(config, "hand_tolerance_deg") and hasattr(config, "dwell_s"):
        # Written from the code of Interact.finished, which has no docstring of its own.
        done = (
            f"`{owner.__name__}.finished`: in the goal region, the estimated hand has stayed "
            f"within `hand_tolerance_deg` ({config.hand_tolerance_deg:g} deg) of its target "
            f"for `dwell_s` ({config.dwell_s:g} s); leaving the region or the tolerance "
            "restarts the dwell"
        )
    else:
        done = f"`{owner.__name__}.finished`: {to_md(_first(_doc(owner.finished)))}"
    return [
        "## Success, termination and truncation",
        "The rules, as `LocoCore.step` (`vrloco_env/core.py`) applies them with the task's "
        "`finished` and `collision_free_success`:",
        "\n".join(
            [
                f'- **Success** (`info["is_success"]`): {to_md(rule, cls.Config)}. In code: the '
                f"task is finished ({done}), {free}.",
                "- **Terminated**: the task is finished (success or not), or a step is blocked "
                "while `EnvConfig.terminate_on_collision` is True (default "
                f"{env.terminate_on_collision}).",
                "- **Truncated**: the horizon has passed without termination (default: "
                f"{_horizon()}): `gym.make(id, max_episode_steps=N)` through gymnasium, "
                "`EnvConfig.max_episode_steps` through the classes "
                "(`vrloco_env/registration.py`).",
            ]
        ),
    ]


def _task_config(cls: type) -> list[str]:
    from vrloco_env.tasks.base import NoConfig

    lines = ["## Task configuration"]
    if cls.Config is NoConfig:
        lines.append(
            f"None (`{cls.__name__}.Config` is `NoConfig`): the room is drawn from "
            "`RoomConfig` (`room=RoomConfig(...)`; its fields are listed on the "
            "[task index](index.md#room-configuration))."
        )
        return lines
    lead = to_md(_first(_doc(cls.Config)), cls.Config)
    lines += [
        f"`{qualname(cls.Config)}`, passed as "
        f'`gym.make("{_env_id(cls)}", task_config={cls.Config.__name__}(...))`. {lead}',
        _config_table(cls.Config, cls.Config),
        "The room's shared parameters are `RoomConfig`'s "
        "([task index](index.md#room-configuration)).",
    ]
    return lines


def _env_id(cls: type) -> str:
    from vrloco_env.tasks import env_id

    return env_id(cls.name)


def _layout_function(cls: type) -> Callable[..., Any] | None:
    """The module-level ``<name>_layout`` function of the task's module (its room)."""
    return getattr(sys.modules[cls.__module__], f"{cls.name}_layout", None)


def task_page(name: str) -> str:
    """The Markdown page of task ``name``."""
    from vrloco_env.tasks import get_task

    cls = get_task(name)
    gym_id = _env_id(cls)
    what, rule = _task_text(cls)
    _, caption = picture_layout(name)
    blocks = [
        f"# {cls.__name__} — `{gym_id}`",
        f"> {to_md(cls.description)}",
        f"![The {name} room of env.reset(seed={PICTURE_SEED})](../img/tasks/{name}.png)",
        f"*{caption}*",
        md_table(
            ("", ""),
            [
                ("Gymnasium id", f'`gym.make("{gym_id}")`'),
                ("task name", f"`{name}` (`vrloco benchmark --tasks {name}`)"),
                ("class", f"`{qualname(cls)}`"),
                ("goal", to_md(cls.description)),
                ("success", to_md(rule, cls.Config)),
                ("collision-free success", "yes" if cls.collision_free_success else "no"),
                ("horizon", f"{_horizon()}, `EnvConfig.max_episode_steps`"),
                ("task configuration", f"`{cls.Config.__name__}`"),
            ],
        ),
        "## What the user must do",
        to_md(what[0].upper() + what[1:] + ".", cls.Config),
        *md_blocks(_doc(cls), cls.Config),
    ]
    func = _layout_function(cls)
    if func is not None:
        blocks += ["### The room", f"`{qualname(func)}`:", *md_blocks(_doc(func), cls.Config)]
    blocks += [*_observation(cls), *_action(), *_reward(), *_ending(cls, rule), *_task_config(cls)]
    info = _task_info(cls)
    blocks.append("## Task `info` keys")
    if info:
        blocks += [
            "Besides the keys every task reports (see the [task index](index.md#shared-by-every"
            "-task)), per user:",
            md_table(
                ("key", "meaning"),
                [(f"`{k}`", v or "named in the class docstring above") for k, v in info.items()],
            ),
        ]
    else:
        blocks.append(
            "None beyond the keys every task reports ([task index](index.md#shared-by-every-task))."
        )
    return make_page(blocks)


def tasks_index() -> str:
    """The Markdown page listing every task."""
    import vrloco_env.env as env_module
    import vrloco_env.tasks as tasks
    from vrloco_env.config import EnvConfig, RewardConfig
    from vrloco_env.world import RoomConfig

    rows = []
    for name in tasks.task_names():
        cls = tasks.get_task(name)
        _, rule = _task_text(cls)
        rows.append(
            (
                f"`{name}`",
                f"`{_env_id(cls)}`",
                to_md(cls.description),
                to_md(rule, cls.Config),
                "yes" if cls.collision_free_success else "no",
                _horizon(),
                f"[{cls.__name__}]({name}.md)",
            )
        )
    new_task = next(p for p in doc_paragraphs(_doc(tasks)) if p.startswith("A new task"))
    info = next(p for p in doc_paragraphs(_doc(env_module)) if p.startswith("``info``"))
    return make_page(
        [
            "# Tasks",
            to_md(_first(_doc(tasks))) + " " + to_md(new_task),
            md_table(
                ("task", "Gymnasium id", "goal", "success", "collision-free", "horizon", "page"),
                rows,
            ),
            "## Shared by every task",
            "Every task has the same action (`Box(-1, 1, (5,), float32)`: walk, turn and three "
            "hand rates), the same reward terms, and observes the same common fields before its "
            "own; each task page lists them in full. " + to_md(info),
            "## Room configuration",
            f"`room=RoomConfig(...)` (`{qualname(RoomConfig)}`). {to_md(_first(_doc(RoomConfig)))}",
            _config_table(RoomConfig),
            "## Reward configuration",
            f"`reward=RewardConfig(...)` (`{qualname(RewardConfig)}`). "
            f"{to_md(_first(_doc(RewardConfig)))}",
            _config_table(RewardConfig),
            "## Environment configuration",
            f"`config=EnvConfig(...)` (`{qualname(EnvConfig)}`). {to_md(_first(_doc(EnvConfig)))}",
            _config_table(EnvConfig),
        ]
    )
