"""Tasks as objects and the observation spec: a new task is one class and one registry line."""

from dataclasses import dataclass

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import vrloco_env  # noqa: F401
from agents.scripted import ObservationLayout, ObsView
from vrloco_env import ENV_IDS
from vrloco_env.observation import Field, ObservationSpec
from vrloco_env.tasks import TASKS, Task, env_id, get_task, register_task
from vrloco_env.tasks.interact import InteractConfig
from vrloco_env.world import (
    Cylinder,
    Layout,
    RoomConfig,
    check_rng,
    finish_layout,
    no_layout_error,
    room_bounds,
)


@dataclass(frozen=True)
class PillarConfig:
    distance_m: float = 3.0


class Pillar(Task):
    """Toy task: reach a goal straight ahead, past one pillar; observes its own pillar range."""

    name = "pillar"
    Config = PillarConfig

    def draw_layout(self, room: RoomConfig, rng: np.random.Generator) -> Layout:
        rng = check_rng(rng)
        bounds = room_bounds(room)
        for _ in range(room.max_attempts):
            start = np.array([-self.config.distance_m / 2, rng.uniform(-0.5, 0.5)])
            goal = start + np.array([self.config.distance_m, 0.0])
            pillar = Cylinder(tuple((start + goal) / 2 + np.array([0.0, 0.6])), 0.2, 1.0)
            layout = finish_layout(room, "pillar", bounds, [pillar], start, 0.0, goal, None, None)
            if layout is not None:
                return layout
        raise no_layout_error(room, "pillar")

    def fields(self):
        return (Field("pillar_side", scale=1.0, doc="+1: the pillar is on the left"),)

    def observe(self, user_step, fresh):
        return {"pillar_side": np.ones((self.batch_size, 1))}


@pytest.fixture
def pillar_task():
    register_task("pillar", Pillar)
    yield
    TASKS.pop("pillar")
    ENV_IDS.pop("VRLoco-Pillar-v0")
    del gym.registry["VRLoco-Pillar-v0"]


def test_a_registered_toy_task_runs_through_make_check_env_and_make_vec(pillar_task):
    assert env_id("pillar") == "VRLoco-Pillar-v0" and "VRLoco-Pillar-v0" in ENV_IDS
    env = gym.make("VRLoco-Pillar-v0", task_config=PillarConfig(distance_m=2.5))
    check_env(env.unwrapped, skip_render_check=True)
    obs, info = env.reset(seed=0)
    spec = env.unwrapped.observation_spec
    assert spec.names[-1] == "pillar_side" and obs[-1] == 1.0
    assert info["distance_to_goal"] == pytest.approx(2.5 - RoomConfig().goal_radius, abs=1e-9)
    walk = np.array([1.0, 0, 0, 0, 0], np.float32)
    for _ in range(80):  # straight ahead: the pillar stands beside the line, the goal on it
        obs, _, terminated, truncated, info = env.step(walk)
        if terminated or truncated:
            break
    assert info["is_success"] and info["collisions"] == 0
    for mode in ("sync", "vector_entry_point"):
        envs = gym.make_vec(
            "VRLoco-Pillar-v0", num_envs=2, vectorization_mode=mode, max_episode_steps=5
        )
        envs.reset(seed=1)
        for _ in range(12):
            obs, *_ = envs.step(np.tile(walk, (2, 1)))
        assert obs.shape == (2, spec.size)
        envs.close()
    with pytest.raises(TypeError, match="takes a PillarConfig"):
        gym.make("VRLoco-Pillar-v0", task_config=InteractConfig())


def test_registry_generates_the_ids_and_names_errors():
    assert {env_id(n) for n in TASKS} <= set(gym.registry)
    with pytest.raises(
        ValueError, match="task='dance': unknown; valid names: approach, avoid, interact"
    ):
        get_task("dance")
    with pytest.raises(TypeError, match="Task subclass"):
        register_task("bad", object)


def test_interact_has_its_own_config_and_fields():
    env = gym.make("VRLoco-Interact-v0", task_config=InteractConfig(hand_tolerance_deg=30.0))
    assert env.unwrapped.core.task.config.hand_tolerance_deg == 30.0
    spec = env.unwrapped.observation_spec
    assert spec.names[-4:] == ["hand_error_yaw", "hand_error_pitch", "hand_error_roll", "dwell"]
    assert "hand_error" not in gym.make("VRLoco-Approach-v0").unwrapped.observation_spec
    with pytest.raises(ValueError, match=r"InteractConfig.dwell_s=0.0: must be in \(0, 30\] s"):
        InteractConfig(dwell_s=0.0)


def test_the_spec_decodes_what_the_env_encodes():
    """Decoded entries equal the env's ground truth (within float32) where nothing saturates."""
    env = gym.make("VRLoco-Approach-v0")
    spec = env.unwrapped.observation_spec
    obs, info = env.reset(seed=2)
    layout = ObservationLayout.from_env(env)
    for _ in range(30):
        obs, *_, info = env.step(np.array([0.7, 0.1, 0, 0, 0], np.float32))
        d = spec.decode(obs)
        view = ObsView.decode(obs[None].astype(np.float64), layout)
        core = env.unwrapped.core
        truth = min(info["distance_to_goal"], 20.0)
        assert d["goal_distance"][0] == pytest.approx(truth, abs=2e-5 * 20)
        assert view.distance[0] == pytest.approx(truth, abs=2e-5 * 20)
        np.testing.assert_allclose(d["rays"], core.last_rays[0], atol=5.0 * 1e-6)
        assert view.heading[0] == pytest.approx(
            np.angle(np.exp(1j * core.ep.virtual_yaw[0])), abs=1e-5
        )
        assert view.steps[0] == info["detected_steps"]
    assert spec.describe().splitlines()[0].startswith("heading")


def test_spec_rejects_duplicates_and_bad_scales():
    with pytest.raises(ValueError, match="unique"):
        ObservationSpec([Field("a"), Field("a")])
    with pytest.raises(ValueError, match=r"Field\('b'\).scale=0"):
        Field("b", scale=0)
    spec = ObservationSpec([Field("x", ("x0", "x1"), 2.0, "m"), Field("y")])
    out = np.zeros((1, 3), np.float32)
    spec.encode("x", [[1.0, 5.0]], out)
    np.testing.assert_array_equal(out, [[0.5, 1.0, 0.0]])  # scaled, then clipped at 1
    np.testing.assert_array_equal(spec.decode(out)["x"], [[1.0, 2.0]])


def test_the_avoid_corridor_is_the_avoid_tasks_own_config():
    import gymnasium as gym

    from vrloco_env.tasks.avoid import AvoidConfig

    env = gym.make(
        "VRLoco-Avoid-v0", task_config=AvoidConfig(corridor_width=2.4, corridor_width_jitter=0.0)
    )
    env.reset(seed=3)
    xmin, xmax, ymin, ymax = env.unwrapped.layout.bounds
    assert ymax - ymin == pytest.approx(2.4) and xmax - xmin == pytest.approx(14.0)
    with pytest.raises(TypeError, match="AvoidConfig"):
        gym.make("VRLoco-Avoid-v0", task_config=object())
