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
    batch = VRLocoVectorEnv(3, task="approach", autoreset_mode=AutoresetMode.DISABLED,
                            estimators=EstimatorConfig(steps=_plugin("custom_steps.py",
                                                                     "PeakSteps")))  # fmt: skip
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
        env = _make("VRLoco-Interact-v0", hand=hand) if name == "mine" else gym.make(
            "VRLoco-Interact-v0", estimators=EstimatorConfig(hand=hand))  # fmt: skip
        env.reset(seed=0)
        ypr = np.array([env.step(STAND)[-1]["est_hand_ypr"] for _ in range(50)])[10:]
        jitter[name] = np.std(np.diff(ypr, axis=0), axis=0)
    assert (jitter["mine"] < 0.75 * jitter["raw"]).all(), jitter
    env = _make("VRLoco-Interact-v0", hand=_plugin("custom_hand.py", "SmoothedHand"))
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    errors = [env.step(np.array([0, 0, *rng.uniform(-0.6, 0.6, 3)], np.float32))[-1]
              ["hand_error_deg"] for _ in range(80)]  # fmt: skip
    assert np.sqrt(np.mean(np.square(errors))) < 12.0


def test_the_steering_example_walks_between_head_and_torso():
    """examples/custom_steering.py: a user walking straight while scanning with the head walks,
    with the blend, off the torso's facing by less than with head steering and more than with
    torso steering."""
    off = {}
    blended = _plugin("custom_steering.py", "BlendedSteering")
    for name in ("head", "torso", blended):
        env = (_make(steering=name, population="gaze_scanners") if name == blended else
               gym.make("VRLoco-Approach-v0", estimators=EstimatorConfig(steering=name),
                        population="gaze_scanners"))  # fmt: skip
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
    ["custom_estimator.py", "custom_steps.py", "custom_hand.py", "custom_steering.py",
     "custom_locomotion.py"],
)  # fmt: skip
def test_each_example_runs_as_a_script(example, capsys):
    """``python examples/<example>`` compares the plug-in with the built-in stage: it runs and
    prints a line for each."""
    runpy.run_path(str(EXAMPLES / example), run_name="__main__")
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) >= 2 and all(lines)
