"""The open pipeline: stage registries, plug-ins, techniques, and the env composing them."""

import gymnasium as gym
import numpy as np
import pytest

import vrloco_env  # noqa: F401
from estimators import stages
from estimators.attitude import AttitudeParams, EkfStage
from estimators.stages import StageError
from vrloco_env.config import EnvConfig, EstimatorConfig, SensorConfig
from vrloco_env.techniques import TECHNIQUES, Technique
from vrloco_env.user import MotionParams

WALK = np.array([0.8, 0.15, 0.2, 0.0, 0.0], np.float32)


def _episode(env, steps=60, seed=4):
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for _ in range(steps):
        obs, r, *_, info = env.step(WALK)
        out += [obs, np.array([r]), info["position"], info["est_ypr"]]
    env.close()
    return np.concatenate([np.ravel(x) for x in out])


# ------------------------------------------------------------------------------ registries
@pytest.mark.parametrize("field", ["attitude", "steps", "hand", "steering", "locomotion"])
def test_unknown_names_list_the_valid_ones(field):
    registry = getattr(stages, field.upper())
    with pytest.raises(ValueError, match=f"EstimatorConfig.{field}='nope': unknown; valid names"):
        EstimatorConfig(**{field: "nope"})
    for name in registry.names():  # every registered name is accepted
        EstimatorConfig(**{field: name})


def test_every_registered_stage_builds_and_satisfies_its_protocol():
    args = {"attitude": (2, 100.0), "steps": (2, 100.0), "hand": (2, 30.0),
            "steering": (2,), "locomotion": (2, 0.7)}  # fmt: skip
    for field, a in args.items():
        registry = getattr(stages, field.upper())
        for name in registry.names():
            stage = registry.build(name, *a)
            assert isinstance(stage, registry.protocol), (field, name)


def test_a_plugin_is_found_by_module_attr_and_by_file_path(tmp_path):
    cfg = EstimatorConfig(attitude="estimators.attitude:EkfStage")
    assert isinstance(stages.ATTITUDE.build(cfg.attitude, 1, 100.0), EkfStage)
    plugin = tmp_path / "my_filter.py"
    plugin.write_text(
        "from estimators.attitude import EkfStage\n"
        "class Mine(EkfStage):\n    name = 'mine'\n"
    )
    stage = stages.ATTITUDE.build(f"{plugin}:Mine", 2, 100.0)
    assert type(stage).__name__ == "Mine"
    with pytest.raises(StageError, match="no such file"):
        stages.ATTITUDE.build(f"{tmp_path / 'absent.py'}:Mine", 1, 100.0)
    with pytest.raises(ValueError, match="has no attribute 'Absent'"):
        EstimatorConfig(attitude="estimators.attitude:Absent")
    with pytest.raises(ValueError, match="cannot import"):
        EstimatorConfig(attitude="no_such_package.mod:Filter")


def test_a_parameter_object_builds_its_stage():
    stage = stages.ATTITUDE.build(AttitudeParams(acc_noise=0.05), 3, 100.0)
    assert isinstance(stage, EkfStage) and stage.params.acc_noise == 0.05


class _NoUpdate:
    def __init__(self, batch_size, fs):
        pass

    def reset(self, rows=None):
        pass


class _Broken:
    def __init__(self, batch_size, fs):
        raise RuntimeError("no calibration file")


def test_a_plugin_that_breaks_the_protocol_or_fails_to_build_is_named():
    with pytest.raises(StageError, match=r"attitude plug-in .*lacks update"):
        stages.ATTITUDE.build(_NoUpdate, 1, 100.0)
    with pytest.raises(StageError, match=r"plug-in '_Broken' failed to build.*calibration"):
        stages.ATTITUDE.build(_Broken, 1, 100.0)


class _Shape(EkfStage):
    """Drops the last sample of every step."""

    def update(self, gyr, acc, mag=None):
        return super().update(gyr, acc, mag)[:, :-1]


class _Nan(EkfStage):
    def update(self, gyr, acc, mag=None):
        q = super().update(gyr, acc, mag)
        q[:, 3] = np.nan
        return q


class _Raises(EkfStage):
    def update(self, gyr, acc, mag=None):
        raise ZeroDivisionError("oops")


@pytest.mark.parametrize(
    ("plugin", "message"),
    [
        (_Shape, r"plug-in '_Shape' returned quat of shape \(1, 9, 4\); expected \(1, 10, 4\)"),
        (_Nan, r"attitude plug-in '_Nan' returned non-finite quat"),
        (_Raises, r"attitude plug-in '_Raises' raised in update.*ZeroDivisionError: oops"),
    ],
)
def test_a_plugin_with_a_bad_output_gets_an_error_naming_stage_and_plugin(plugin, message):
    env = gym.make("VRLoco-Approach-v0", estimators=EstimatorConfig(attitude=plugin))
    env.reset(seed=0)
    with pytest.raises(StageError, match=message):
        env.step(WALK)
    env.close()


def _bad_steering(batch_size):
    class Steer:
        def reset(self, rows=None):
            pass

        def update(self, head_yaw, torso_yaw, torso_valid):
            return np.zeros(batch_size + 1)

    return Steer()


def test_a_steering_plugin_returning_the_wrong_shape_is_named():
    env = gym.make("VRLoco-Approach-v0", estimators=EstimatorConfig(steering=_bad_steering))
    env.reset(seed=0)
    with pytest.raises(StageError, match=r"steering plug-in '_bad_steering' returned yaw of shape"):
        env.step(WALK)
    env.close()


# ------------------------------------------------------------------------------ techniques
def test_the_default_env_is_the_seed000_technique_bit_for_bit():
    a = _episode(gym.make("VRLoco-Approach-v0"))
    b = _episode(gym.make("VRLoco-Approach-v0", technique="seed000"))
    np.testing.assert_array_equal(a, b)
    assert gym.make("VRLoco-Approach-v0").unwrapped.technique == "seed000"


@pytest.mark.parametrize("name", ["smooth", "torso_steering", "paper_literal"])
def test_a_technique_equals_its_estimator_config(name):
    tech = TECHNIQUES[name]
    a = _episode(gym.make("VRLoco-Avoid-v0", technique=name))
    b = _episode(gym.make("VRLoco-Avoid-v0", estimators=tech.estimators,
                          sensor_preset=tech.sensor_preset))  # fmt: skip
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, _episode(gym.make("VRLoco-Avoid-v0")))  # and it changes things


def test_the_consumer_technique_is_the_consumer_preset():
    env = gym.make("VRLoco-Approach-v0", technique="seed000_consumer")
    assert env.unwrapped.sensors.preset_name == "consumer_mems"
    assert env.unwrapped.technique == "seed000_consumer"
    shorthand = gym.make("VRLoco-Approach-v0", sensor_preset="consumer_mems")
    assert shorthand.unwrapped.technique == "seed000_consumer"
    np.testing.assert_array_equal(_episode(env), _episode(shorthand))


def test_an_unregistered_technique_object_and_the_vector_env():
    tech = Technique("mine", "smooth on consumer", "consumer_mems",
                     EstimatorConfig(locomotion="smooth"))  # fmt: skip
    env = gym.make("VRLoco-Approach-v0", technique=tech)
    assert env.unwrapped.technique == "mine"
    envs = gym.make_vec("VRLoco-Approach-v0", num_envs=2, technique=tech)
    assert envs.unwrapped.technique == "mine"
    assert envs.unwrapped.core.users.locomotion.__class__.__name__ == "SmoothLocomotion"
    envs.close()


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"technique": "vqf", "estimators": EstimatorConfig()}, "contradicts technique='vqf'"),
        ({"technique": "seed000", "sensor_preset": "consumer_mems"}, "contradicts technique"),
        ({"technique": "seed000_consumer", "sensors": SensorConfig(imu="ig500n")}, None),
        ({"technique": "smooth", "locomotion": "eq17"}, "locomotion='eq17' contradicts"),
        ({"sensors": SensorConfig(imu="consumer_mems"), "sensor_preset": "ig500n"},
         "sensor_preset='ig500n' contradicts"),
        ({"technique": "nope"}, "technique='nope': unknown; valid names: seed000"),
        ({"config": EnvConfig(motion=MotionParams(imu_rate_hz=200.0))},
         "MotionParams.imu_rate_hz=200.0 contradicts SensorConfig.imu_rate_hz"),
    ],
)
def test_contradicting_arguments_are_an_error(kwargs, message):
    if message is None:  # sensors.imu at its default defers to the technique
        env = gym.make("VRLoco-Approach-v0", **kwargs)
        assert env.unwrapped.sensors.preset_name == "consumer_mems"
        return
    with pytest.raises(ValueError, match=message):
        gym.make("VRLoco-Approach-v0", **kwargs)


def test_motion_params_follow_the_sensors_without_overwriting_a_choice():
    env = gym.make("VRLoco-Approach-v0", sensors=SensorConfig(imu_rate_hz=200.0))
    assert env.unwrapped.core.users.motion_params.imu_rate_hz == 200.0
    env = gym.make("VRLoco-Approach-v0", sensors=SensorConfig(imu_rate_hz=200.0),
                   config=EnvConfig(motion=MotionParams(imu_rate_hz=200.0)))  # fmt: skip
    assert env.unwrapped.core.users.motion_params.imu_rate_hz == 200.0


# ------------------------------------------------------------------------------ steering
def test_torso_steering_walks_straight_while_the_head_looks_around():
    """A user walks in place facing +x while scanning +-35 deg left and right (head on torso).
    Head steering walks where the head looks; torso steering follows the shoulders."""
    from vrloco_env.core import LocoCore
    from vrloco_env.env import make_configs
    from vrloco_env.user import Intent

    headings = {}
    for name in ("seed000", "torso_steering"):
        core = LocoCore("approach", 3, *make_configs(technique=name))
        for i in range(3):
            core.generators[i] = np.random.default_rng(30 + i)
        core.reset()
        users = core.users
        start_yaw = np.array([lay.start[2] for lay in core.layouts])[None, :]
        position = np.zeros((3, 2))
        positions = []
        for _ in range(80):
            intent = Intent(
                cadence=np.full(3, 1.8), turn_rate=np.zeros(3), hand_rates=np.zeros((3, 3)),
                gesture_amplitude=np.tile([np.deg2rad(35.0), 0.0, 0.0], (3, 1)),
                gesture_frequency=np.tile([0.3, 0.3, 0.3], (3, 1)), lean=np.zeros(3),
            )  # fmt: skip
            position = position + users.step(intent).displacement
            positions.append(position)
        path = np.diff(np.array(positions), axis=0)  # (T, B, 2)
        moving = np.hypot(path[..., 0], path[..., 1]) > 1e-6
        direction = np.arctan2(path[..., 1], path[..., 0])
        err = np.rad2deg(np.angle(np.exp(1j * (direction - start_yaw))))[moving]
        headings[name] = np.sqrt(np.mean(err**2))
    # The head sweeps +-35 deg: the walk follows it (RMS ~ 35 / sqrt 2 = 25 deg) ...
    assert headings["seed000"] > 15.0
    # ... while the torso keeps facing the start heading.
    assert headings["torso_steering"] < 5.0


def _walking_episode(env, seed: int, steps: int = 80) -> list:
    """Observations, rewards and every info value of ``steps`` steps of a walking user."""
    obs, _ = env.reset(seed=seed)
    out = [obs]
    rng = np.random.default_rng(seed)
    for _ in range(steps):
        action = rng.uniform(-1.0, 1.0, 5).astype(np.float32)
        action[0] = 1.0  # walking: steps, movement, the locomotion stage's filters
        obs, reward, terminated, truncated, info = env.step(action)
        out += [obs, reward, *(info[k] for k in sorted(info))]
        if terminated or truncated:
            break
    return out


@pytest.mark.parametrize("name", sorted(TECHNIQUES))
def test_an_env_used_before_replays_a_seed_bit_for_bit(name):
    """No stage carries anything from one episode into the next: the env's second episode is
    what a new env gives for that seed, every observation and info value to the bit."""
    used = gym.make("VRLoco-Interact-v0", technique=name)
    _walking_episode(used, 3)
    again = _walking_episode(used, 4)
    fresh = _walking_episode(gym.make("VRLoco-Interact-v0", technique=name), 4)
    assert len(again) == len(fresh)
    for k, (a, b) in enumerate(zip(again, fresh, strict=True)):
        np.testing.assert_array_equal(a, b, err_msg=f"value {k}")
