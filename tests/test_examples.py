"""The plug-in examples in examples/: one per stage, each run in the env through its file path
("examples/custom_x.py:Cls", as a user selects it), behind the checked proxy."""

import runpy
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import vrloco_env  # noqa: F401  (registers the ids)
from estimators.checked import CheckedStage
from vrloco_env.config import EstimatorConfig
from vrloco_env.vector import VRLocoVectorEnv

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
WALK = np.array([0.8, 0.0, 0.0, 0.0, 0.0], np.float32)
STAND = np.zeros(5, np.float32)


def _make(task: str = "VRLoco-Approach-v0", **stages_and_kw):
    kw = {k: stages_and_kw.pop(k) for k in ("population",) if k in stages_and_kw}
    env = gym.make(task, estimators=EstimatorConfig(**stages_and_kw), **kw)
    for field in stages_and_kw:
        assert isinstance(getattr(env.unwrapped.core.users.stages, field), CheckedStage)
    return env


def _plugin(file: str, cls: str) -> str:
    return f"{EXAMPLES / file}:{cls}"


def test_the_attitude_example_tracks_the_head_as_well_as_the_ekf_nearly():
    """examples/custom_estimator.py: the complementary filter's attitude error, walking, stays
    within 1.5 times the EKF's and under 4 deg at every step."""
    mine = _make(attitude=_plugin("custom_estimator.py", "ComplementaryFilter"))
    ekf = gym.make("VRLoco-Approach-v0")
    errors = {}
    for name, env in (("mine", mine), ("ekf", ekf)):
        env.reset(seed=1)
        errors[name] = np.array([env.step(WALK)[-1]["attitude_error_deg"] for _ in range(100)])
    rms = {k: np.sqrt(np.mean(v**2)) for k, v in errors.items()}
    assert rms["mine"] < 1.5 * rms["ekf"] and errors["mine"].max() < 4.0, rms


def test_the_steps_example_counts_the_steps_taken_and_none_standing():
    """examples/custom_steps.py: 10 s of stepping in place, the detected steps within one of
    the steps taken; 3 s of standing after, none; in a batch it sheds users (TakesUsers)."""
    env = _make(steps=_plugin("custom_steps.py", "PeakSteps"))
    env.reset(seed=2)
    walked = [env.step(WALK)[-1] for _ in range(100)]
    detected = sum(i["detected_steps"] for i in walked)
    taken = sum(i["true_steps"] for i in walked)
    assert taken >= 15 and abs(detected - taken) <= 1, (detected, taken)
    for _ in range(10):  # the last step's report
        env.step(STAND)
    assert sum(env.step(STAND)[-1]["detected_steps"] for _ in range(30)) == 0
    batch = VRLocoVectorEnv(
        3,
        task="approach",
        autoreset_mode=AutoresetMode.DISABLED,
        estimators=EstimatorConfig(steps=_plugin("custom_steps.py", "PeakSteps")),
    )
    assert batch.can_take_users
    batch.reset(seed=[0, 1, 2])
    for _ in range(20):
        batch.step(np.tile(WALK, (3, 1)))
    batch.take_users(np.array([2, 0]))
    steps = sum(batch.step(np.tile(WALK, (2, 1)))[-1]["detected_steps"] for _ in range(30))
    assert steps.shape == (2,) and (steps >= 5).all()


def test_the_hand_example_smooths_the_raw_angles_and_follows_the_hand():
    """examples/custom_hand.py: a still hand's estimate jitters less than the raw angles' (step
    to step), and a turning hand is followed within 12 deg RMS."""
    jitter = {}
    for name, hand in (("mine", _plugin("custom_hand.py", "SmoothedHand")), ("raw", "raw")):
        env = (
            _make("VRLoco-Interact-v0", hand=hand)
            if name == "mine"
            else gym.make("VRLoco-Interact-v0", estimators=EstimatorConfig(hand=hand))
        )
        env.reset(seed=0)
        ypr = np.array([env.step(STAND)[-1]["est_hand_ypr"] for _ in range(50)])[10:]
        jitter[name] = np.std(np.diff(ypr, axis=0), axis=0)
    assert (jitter["mine"] < 0.75 * jitter["raw"]).all(), jitter
    env = _make("VRLoco-Interact-v0", hand=_plugin("custom_hand.py", "SmoothedHand"))
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    errors = [
        env.step(np.array([0, 0, *rng.uniform(-0.6, 0.6, 3)], np.float32))[-1]["hand_error_deg"]
        for _ in range(80)
    ]
    assert np.sqrt(np.mean(np.square(errors))) < 12.0


def test_the_steering_example_walks_between_head_and_torso():
    """examples/custom_steering.py: a user walking straight while scanning with the head walks,
    with the blend, off the torso's facing by less than with head steering and more than with
    torso steering."""
    off = {}
    blended = _plugin("custom_steering.py", "BlendedSteering")
    for name in ("head", "torso", blended):
        env = (
            _make(steering=name, population="gaze_scanners")
            if name == blended
            else gym.make(
                "VRLoco-Approach-v0",
                estimators=EstimatorConfig(steering=name),
                population="gaze_scanners",
            )
        )
        env.reset(seed=0)
        infos = [env.step(WALK)[-1] for _ in range(100)]
        d = np.array([i["walk_yaw_deg"] - i["true_body_yaw_deg"] for i in infos])
        off[name] = np.sqrt(np.mean(((d + 180.0) % 360.0 - 180.0) ** 2))
    assert off["torso"] + 5.0 < off[blended] < off["head"] - 5.0, off


def test_the_locomotion_example_glides_every_detected_step():
    """examples/custom_locomotion.py: no control step moves more than speed x dt, and once the
    user stands still the path travelled is the step length times the steps detected."""
    env = _make(locomotion=_plugin("custom_locomotion.py", "GlideLocomotion"))
    env.reset(seed=3)
    infos = [env.step(WALK)[-1] for _ in range(60)] + [env.step(STAND)[-1] for _ in range(40)]
    path = np.array([i["position"] for i in infos])
    assert np.linalg.norm(np.diff(path, axis=0), axis=-1).max() <= 1.4 * 0.1 + 1e-9
    locomotion = env.unwrapped.core.users.locomotion
    assert isinstance(locomotion, CheckedStage)
    detected = sum(i["detected_steps"] for i in infos)
    assert detected >= 10
    np.testing.assert_allclose(locomotion.distance, 0.7 * detected, rtol=1e-12)


@pytest.mark.parametrize(
    "example",
    [
        "custom_estimator.py",
        "custom_steps.py",
        "custom_hand.py",
        "custom_steering.py",
        "custom_locomotion.py",
    ],
)
def test_each_example_runs_as_a_script(example, capsys):
    """``python examples/<example>`` compares the plug-in with the built-in stage: it runs and
    prints a line for each."""
    runpy.run_path(str(EXAMPLES / example), run_name="__main__")
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) >= 2 and all(lines)


# --------------------------------------------------------------------------- task and policy


@pytest.fixture
def turn_around():
    """examples/custom_task.py registered as ``turn_around`` by its path (the route its docstring
    shows), unregistered afterwards so that no other test sees it."""
    from vrloco_env.registration import ENV_IDS
    from vrloco_env.tasks import TASKS, env_id, register_task

    register_task("turn_around", _plugin("custom_task.py", "TurnAround"))
    yield "turn_around"
    TASKS.pop("turn_around", None)
    ENV_IDS.pop(env_id("turn_around"), None)
    gym.registry.pop(env_id("turn_around"), None)


def _walker() -> str:
    return _plugin("custom_policy.py", "CautiousWalker")


def test_the_task_example_puts_the_goal_behind_the_start_and_the_pillar_in_the_way(turn_around):
    """examples/custom_task.py: every room starts the user facing away from the goal, with the
    pillar on the straight way; a user standing still never finishes; the goal seeker's episode
    succeeds on the very step its virtual position enters the goal disc, without a collision."""
    from agents.benchmark.policies import build_policy

    env = gym.make("VRLoco-TurnAround-v0")
    for seed in range(4):
        env.reset(seed=seed)
        layout = env.unwrapped.core.layouts[0]
        (sx, sy, yaw), (gx, gy) = layout.start, layout.goal
        behind = np.arctan2(gy - sy, gx - sx) - yaw
        assert abs((behind + np.pi) % (2 * np.pi) - np.pi) > np.deg2rad(170.0)
        (pillar,) = layout.obstacles
        assert min(sx, gx) < pillar.center[0] < max(sx, gx)
        assert abs(pillar.center[1]) < pillar.radius  # it blocks the straight way
        assert layout.shortest_path_length > np.hypot(gx - sx, gy - sy) - layout.goal_radius
    env.reset(seed=0)
    assert not any(env.step(STAND)[-1]["task_done"] for _ in range(30))
    obs, info = env.reset(seed=0)
    layout = env.unwrapped.core.layouts[0]
    goal, radius = np.array(layout.goal), layout.goal_radius
    policy = build_policy("goal_seeker", env)
    policy.reset()
    for _ in range(300):
        obs, _, terminated, truncated, info = env.step(policy.act(obs))
        inside = np.hypot(*(info["position"] - goal)) <= radius
        assert bool(info["is_success"]) == inside == terminated, info["position"]
        if terminated or truncated:
            break
    assert info["is_success"] and info["collisions"] == 0 and info["elapsed_time"] > 3.0


def test_the_policy_example_walks_to_the_obstacle_and_stops_short_of_it():
    """examples/custom_policy.py, three users of the Avoid corridor: each walks more than 3 m
    toward the end line, stops without a collision before the obstacle that blocks it and stays
    there; each user's actions are those it gets alone (no row leaks into another)."""
    from agents.benchmark.policies import build_policy
    from agents.scripted import ObsView

    env = gym.make_vec("VRLoco-Avoid-v0", num_envs=3, vectorization_mode="vector_entry_point")
    policy = build_policy(_walker(), env)
    assert type(policy).__name__ == "CautiousWalker" and policy.batched
    obs, info = env.reset(seed=[0, 1, 2])
    policy.reset()
    start, seen, acts, path = info["position"].copy(), [], [], []
    for _ in range(120):
        seen.append(obs)
        acts.append(policy.act(obs))
        obs, _, terminated, truncated, info = env.step(acts[-1])
        path.append(info["position"].copy())
    assert not (terminated | truncated).any()
    assert (info["collisions"] == 0).all() and (info["distance_to_goal"] > 0).all()
    assert (info["position"][:, 0] - start[:, 0] > 3.0).all()
    np.testing.assert_array_equal(path[-30], path[-1])  # stood still for the last 3 s
    ahead = ObsView.decode(obs.astype(np.float64), policy.layout).rays[:, policy.front].min(1)
    assert ((ahead > 0.5) & (ahead < policy.go_m)).all(), ahead  # the obstacle stopped it
    alone = build_policy(_walker(), env)
    alone.reset()
    np.testing.assert_array_equal([alone.act(o[1]) for o in seen], np.array(acts)[:, 1])


def test_the_task_and_policy_examples_run_in_the_benchmark(turn_around):
    """Both examples through run_benchmark's own resolution (the task by its registered name,
    the policy by its path): the goal seeker passes the pillar in both episodes; the cautious
    walker, which goes round nothing, stops in front of it in both, without a collision."""
    from agents.benchmark import run_benchmark

    rows = run_benchmark(
        tasks=[turn_around],
        policies=["goal_seeker", _walker()],
        techniques=["zhang2021"],
        episodes=2,
        workers=1,
        out_dir=None,
        progress=False,
        print_table=False,
    )
    by_policy = {r["policy"]: r for r in rows}
    assert set(by_policy) == {"goal_seeker", _walker()}
    assert all(r["task"] == "turn_around" and r["episodes"] == 2 for r in rows)
    assert by_policy["goal_seeker"]["success_rate"] == 1.0
    assert by_policy["goal_seeker"]["collision_rate"] == 0.0
    assert by_policy[_walker()]["success_rate"] == 0.0
    assert by_policy[_walker()]["collision_rate"] == 0.0


def test_the_task_and_policy_examples_run_from_the_command_line(tmp_path, capsys):
    """``python examples/custom_task.py benchmark ...`` registers the task and runs ``vrloco
    benchmark`` on it; ``vrloco benchmark --policies examples/custom_policy.py:CautiousWalker``
    runs the policy; each writes its cell's row to benchmark.csv."""
    import csv
    import sys

    from agents.cli import main
    from vrloco_env.registration import ENV_IDS
    from vrloco_env.tasks import TASKS, env_id

    args = ["--techniques", "zhang2021", "--episodes", "2", "--workers", "1"]
    argv = sys.argv
    sys.argv = [
        str(EXAMPLES / "custom_task.py"),
        "benchmark",
        "--tasks",
        "turn_around",
        "--policies",
        "goal_seeker",
        *args,
        "--out",
        str(tmp_path / "task"),
    ]
    try:
        with pytest.raises(SystemExit) as done:
            runpy.run_path(sys.argv[0], run_name="__main__")
    finally:
        sys.argv = argv
        TASKS.pop("turn_around", None)
        ENV_IDS.pop(env_id("turn_around"), None)
        gym.registry.pop(env_id("turn_around"), None)
    assert done.value.code == 0
    assert (
        main(
            [
                "benchmark",
                "--tasks",
                "approach",
                "--policies",
                _walker(),
                *args,
                "--out",
                str(tmp_path / "policy"),
            ]
        )
        == 0
    )
    capsys.readouterr()
    for folder, task, policy in (
        ("task", "turn_around", "goal_seeker"),
        ("policy", "approach", _walker()),
    ):
        with open(tmp_path / folder / "benchmark.csv", newline="") as f:
            (row,) = csv.DictReader(f)
        assert (row["task"], row["policy"], row["episodes"]) == (task, policy, "2")
