"""Copies of an env (``copy.deepcopy``, ``pickle``, ``copy.copy``) go on bit for bit like the
original: observations, rewards, flags and every numeric info value, step after step.

Each case resets an env with a seed, steps it a few steps (so the copy is taken mid-episode, with
the users' motion, sensors, estimators and random streams all under way), copies it three ways,
then steps the original and the copies side by side with one fixed action sequence that stands,
walks, turns left, turns right and moves the hand.
"""

from __future__ import annotations

import copy
import pickle
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import vrloco_env  # noqa: F401  (registers the ids)
from vrloco_env.env import VRLocoEnv
from vrloco_env.tasks import env_id, task_names
from vrloco_env.techniques import TECHNIQUES
from vrloco_env.user.population import population_names
from vrloco_env.vector import VRLocoVectorEnv

BEFORE = 6  # steps before the copy
AFTER = 24  # steps of original and copies side by side
SEED = 3

COPIES: dict[str, Callable[[Any], Any]] = {
    "deepcopy": copy.deepcopy,
    "pickle": lambda env: pickle.loads(pickle.dumps(env)),
    "copy": copy.copy,
}


def _actions(num_envs: int | None = None) -> np.ndarray:
    """(BEFORE + AFTER, [num_envs,] 5): stand, walk, turn left, walk on, turn right, with the
    hand turning; each sub-env of a vector env turns its own way and walks at its own pace."""
    n = BEFORE + AFTER
    a = np.zeros((n, 5), np.float32)
    a[:3, 0] = -1.0  # stand
    a[3:, 0] = 0.8  # walk
    a[BEFORE + 2 : BEFORE + 10, 1] = 0.8  # turn left
    a[BEFORE + 16 : BEFORE + 22, 1] = -0.6  # turn right
    a[:, 2] = 0.4 * np.sin(np.arange(n) / 3.0)  # hand yaw rate
    a[:, 3] = -0.3  # hand pitch rate
    if num_envs is None:
        return a
    out = np.repeat(a[:, None], num_envs, axis=1)
    out[:, :, 1] *= np.where(np.arange(num_envs) % 2, -1.0, 1.0)
    out[3:, :, 0] = np.linspace(0.5, 1.0, num_envs)
    return out


def _assert_same(a: Any, b: Any, where: str) -> None:
    """``a`` and ``b`` equal to the bit (NaN where NaN); dicts key by key, numbers as arrays."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys(), f"{where}: keys differ"
        for k in a:
            _assert_same(a[k], b[k], f"{where}[{k!r}]")
        return
    x, y = np.asarray(a), np.asarray(b)
    if x.dtype.kind not in "biuf":
        return
    np.testing.assert_array_equal(x, y, err_msg=where, strict=True)  # shape and dtype too


def _run_side_by_side(
    make: Callable[[], Any],
    copy_of: Callable[[Any], Any] = lambda e: e,
    num_envs: int | None = None,
) -> list[dict]:
    """Reset, step BEFORE steps, copy ``copy_of(env)`` three ways, step all AFTER steps and
    compare each copy's step with the original's. Returns the original's infos after the copy."""
    env = make()
    env.reset(seed=SEED)
    acts = _actions(num_envs)
    for k in range(BEFORE):
        env.step(acts[k])
    original = copy_of(env)
    copies = {name: fn(original) for name, fn in COPIES.items()}
    for c in copies.values():
        assert c is not original and c.unwrapped.core is not original.unwrapped.core
    infos = []
    for k in range(BEFORE, BEFORE + AFTER):
        ref = original.step(acts[k])
        infos.append(ref[4])
        for name, c in copies.items():
            out = c.step(acts[k])
            for part, x, y in zip(
                ("obs", "reward", "terminated", "truncated", "info"), ref, out, strict=True
            ):
                _assert_same(x, y, f"{name} copy, step {k}, {part}")
    return infos


def _assert_walked_and_turned(infos: list[dict]) -> None:
    """The compared steps covered walking (true steps, or for a technique that moves the body
    without steps, the virtual body moving) and turning (of the true body)."""
    steps = sum(np.sum(i["true_steps"]) for i in infos)
    moved = float(np.min(np.asarray(infos[-1]["walked"]) - np.asarray(infos[0]["walked"])))
    yaw = np.array([i["true_body_yaw_deg"] for i in infos])
    assert steps >= 4 or moved >= 0.5, f"only {steps} true steps and {moved:.2f} m while compared"
    assert np.ptp(yaw, axis=0).min() > 20.0, "the true body hardly turned while compared"


def _techniques_by_task() -> list[tuple[str, str]]:
    """Every task with the default technique, and every technique once, with the tasks in
    turn (so techniques meet hand tasks too)."""
    tasks = task_names()
    cases = [(t, "zhang2021") for t in tasks]
    cases += [(tasks[i % len(tasks)], tech) for i, tech in enumerate(TECHNIQUES)]
    return list(dict.fromkeys(cases))


@pytest.mark.parametrize(("task", "technique"), _techniques_by_task())
def test_single_env_copies_go_on_like_the_original(task, technique):
    infos = _run_side_by_side(
        lambda: gym.make(env_id(task), technique=technique), copy_of=lambda env: env.unwrapped
    )
    _assert_walked_and_turned(infos)


@pytest.mark.parametrize("task", ["approach", "interact"])
def test_wrapped_env_deep_copies_go_on_like_the_original(task):
    """``gym.make``'s wrapper stack, deep-copied and pickled as a whole (``copy.copy`` of it is
    gymnasium's shallow wrapper copy, which shares the env: the test copies the env itself)."""
    env = gym.make(env_id(task), population="typical")
    env.reset(seed=SEED)
    acts = _actions()
    for k in range(BEFORE):
        env.step(acts[k])
    copies = [copy.deepcopy(env), pickle.loads(pickle.dumps(env))]
    for k in range(BEFORE, BEFORE + AFTER):
        ref = env.step(acts[k])
        for c in copies:
            for x, y in zip(ref, c.step(acts[k]), strict=True):
                _assert_same(x, y, f"step {k}")


@pytest.mark.parametrize("population", ["typical", "nodders"])
def test_copies_of_a_population_with_head_behaviour_go_on_like_the_original(population):
    infos = _run_side_by_side(
        lambda: gym.make("VRLoco-Interact-v0", population=population),
        copy_of=lambda env: env.unwrapped,
    )
    _assert_walked_and_turned(infos)
    head = np.array([i["true_ypr"][0] - i["true_body_yaw_deg"] for i in infos])
    head = (head + 180.0) % 360.0 - 180.0  # the head's yaw on the torso (deg)
    assert np.ptp(head) > 1.0  # the head turned on the torso: the behaviour acted


def test_visual_inertial_copies_go_on_like_the_original():
    infos = _run_side_by_side(
        lambda: gym.make("VRLoco-Approach-v0", pose_source="visual_inertial"),
        copy_of=lambda env: env.unwrapped,
    )
    _assert_walked_and_turned(infos)


@pytest.mark.parametrize(
    ("task", "config"),
    [
        ("approach", {}),
        ("interact", {"population": "typical"}),
        ("avoid", {"technique": "vqf"}),
        ("reach", {"pose_source": "visual_inertial"}),
    ],
)
def test_vector_env_copies_go_on_like_the_original(task, config):
    """Mid-episode, with autoresets after the copy (short episodes)."""
    n = 3
    infos = _run_side_by_side(
        lambda: gym.make_vec(env_id(task), num_envs=n, max_episode_steps=14, **config),
        num_envs=n,
    )
    assert any("final_obs" in i for i in infos)  # sub-envs were reset after the copy
    _assert_walked_and_turned(infos)


def test_vector_env_copies_go_on_after_take_users():
    from gymnasium.vector import AutoresetMode

    def make():
        return VRLocoVectorEnv(
            4, task="interact", population="typical", autoreset_mode=AutoresetMode.DISABLED
        )

    envs = make()
    envs.reset(seed=SEED)
    acts = _actions(4)
    for k in range(BEFORE):
        envs.step(acts[k])
    envs.take_users([3, 1])
    for name, fn in COPIES.items():
        original, c = copy.deepcopy(envs), fn(envs)
        for k in range(BEFORE, BEFORE + AFTER):
            for x, y in zip(original.step(acts[k, [3, 1]]), c.step(acts[k, [3, 1]]), strict=True):
                _assert_same(x, y, f"{name} copy, step {k}")


def test_copy_taken_before_reset_matches_the_original_reset_with_the_same_seed():
    env = VRLocoEnv("avoid", technique="smooth")
    copies = [fn(env) for fn in COPIES.values()]
    acts = _actions()
    outs = [e.reset(seed=SEED) for e in (env, *copies)]
    for k in range(len(acts)):
        outs = [e.step(acts[k]) for e in (env, *copies)]
        for out in outs[1:]:
            for x, y in zip(outs[0], out, strict=True):
                _assert_same(x, y, f"step {k}")


def test_rgb_array_copy_builds_its_own_world_and_renders_the_same_picture():
    env = gym.make("VRLoco-Approach-v0", render_mode="rgb_array")
    env.reset(seed=SEED)
    acts = _actions()
    for k in range(BEFORE):
        env.step(acts[k])
    env.render()  # the original's PyBullet world exists
    c = copy.deepcopy(env)
    assert c.unwrapped._sim is None
    for k in range(BEFORE, BEFORE + 3):
        env.step(acts[k])
        c.step(acts[k])
    np.testing.assert_array_equal(env.render(), c.render())
    assert c.unwrapped._sim is not env.unwrapped._sim
    c.close()  # closing the copy leaves the original's world alone
    assert env.render().shape == (480, 960, 3)
    env.close()


def test_what_cannot_be_copied_says_so():
    from vrloco_env.world.sim import Simulation

    env = VRLocoEnv(render_mode="human")  # builds no window before reset
    for fn in COPIES.values():
        with pytest.raises(TypeError, match="render_mode='human' cannot be copied"):
            fn(env)
    with Simulation() as sim:
        for fn in COPIES.values():
            with pytest.raises(TypeError, match=r"Simulation .* cannot be copied or pickled"):
                fn(sim)


@pytest.mark.slow
@pytest.mark.parametrize("population", [None, *population_names()])
@pytest.mark.parametrize("technique", list(TECHNIQUES))
@pytest.mark.parametrize("task", task_names())
def test_every_task_technique_and_population_copies_exactly(task, technique, population):
    infos = _run_side_by_side(
        lambda: gym.make(env_id(task), technique=technique, population=population),
        copy_of=lambda env: env.unwrapped,
    )
    _assert_walked_and_turned(infos)
