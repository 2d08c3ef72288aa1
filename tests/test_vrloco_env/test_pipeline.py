"""The open pipeline: stage registries, plug-ins, techniques, and the env composing them."""

import pickle
import sys
import textwrap
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from _batch_walk import sized
from gymnasium.vector import AutoresetMode

import vrloco_env  # noqa: F401
from estimators import stage_docs, stages
from estimators.attitude import AttitudeParams, EkfStage
from estimators.checked import CheckedStage
from estimators.registry import StageError, protocol_members
from estimators.stages import Locomotion
from vrloco_env import pipeline
from vrloco_env.config import EnvConfig, EstimatorConfig, SensorConfig
from vrloco_env.techniques import TECHNIQUES, Technique
from vrloco_env.user import MotionParams
from vrloco_env.vector import VRLocoVectorEnv

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
    args = {
        "attitude": (2, 100.0),
        "steps": (2, 100.0),
        "hand": (2, 30.0),
        "steering": (2,),
        "locomotion": (2, 0.7),
    }
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
        "from estimators.attitude import EkfStage\nclass Mine(EkfStage):\n    name = 'mine'\n"
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
        (
            _Nan,
            r"attitude plug-in '_Nan' returned quat at user 0, sample 3: "
            r"\[nan, nan, nan, nan\], which breaks the rule: finite \(no NaN or inf\)",
        ),
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


# ------------------------------------------------------------------------------ checked proxy
_TOYS = '''
import numpy as np

from estimators.attitude import EkfStage
from estimators.locomotion.dead_reckoning import DeadReckoning
from estimators.stages import GaitChunk
from estimators.hand import RawHand


class ZeroQuat(EkfStage):
    def update(self, gyr, acc, mag=None):
        q = super().update(gyr, acc, mag)
        q[:, 4] = 0.0
        return q


class LongQuat(EkfStage):
    scale = 1.01

    def update(self, gyr, acc, mag=None):
        return super().update(gyr, acc, mag) * self.scale


class AlmostUnitQuat(LongQuat):
    scale = 1.0009  # inside the stated tolerance


class StepAtEnd:
    """A step confirmed at every chunk's last sample, its heel strike ``offset`` s after it."""

    offset, resets = 0.0, True

    def __init__(self, batch_size, fs):
        self.fs, self.clock = fs, np.zeros(batch_size)

    def reset(self, rows=None):
        if self.resets:
            self.clock[slice(None) if rows is None else rows] = 0

    def update(self, acc, gyr, quat):
        b, n = acc.shape[:2]
        steps = np.zeros((b, n), np.int8)
        steps[:, -1] = 1
        t = np.full((b, n, 2), np.nan)
        t[:, -1, 0] = (self.clock + n - 1) / self.fs + self.offset
        self.clock += n
        return GaitChunk(np.ones((b, n), np.int8), steps, t, np.arange(n) / self.fs)


class FutureStep(StepAtEnd):
    offset = 0.5


class ClockNeverResets(StepAtEnd):
    resets = False


class NegativeSteps(StepAtEnd):
    def update(self, acc, gyr, quat):
        chunk = super().update(acc, gyr, quat)
        chunk.steps[:] = -1
        return chunk


class PitchHand(RawHand):
    def update(self, frames):
        ypr, valid = super().update(frames)
        ypr[:, :, 1] = 4.0  # rad: beyond the pole, a wrong unit
        return ypr, np.ones_like(valid)


class NanHand(RawHand):
    def update(self, frames):
        ypr, valid = super().update(frames)
        return np.full_like(ypr, np.nan), np.ones_like(valid)


class NanSteering:
    def __init__(self, batch_size):
        pass

    def reset(self, rows=None):
        pass

    def update(self, head_yaw, torso_yaw, torso_valid):
        return np.full(np.shape(head_yaw), np.nan)


class FarAway(DeadReckoning):
    def update(self, steps, yaw, dt, bearing=None):
        return super().update(steps, yaw, dt, bearing) + 1e9


class LostHeading(DeadReckoning):
    @property
    def heading(self):
        return np.full(self.batch_size, np.nan)
'''


@pytest.fixture(scope="module")
def toys(tmp_path_factory) -> str:
    """The path of a file of deliberately bad plug-ins, one class each."""
    path = tmp_path_factory.mktemp("plugins") / "toys.py"
    path.write_text(textwrap.dedent(_TOYS))
    return str(path)


def _steps_until_error(env, steps: int = 40, seed: int = 0) -> None:
    env.reset(seed=seed)
    for _ in range(steps):
        env.step(WALK)


_RULE = "which breaks the rule: "


@pytest.mark.parametrize(
    ("field", "toy", "message"),
    [
        (
            "attitude",
            "ZeroQuat",
            r"returned quat at user 0, sample 4: \[0, 0, 0, 0\], "
            + _RULE
            + r"not the zero quaternion",
        ),
        (
            "attitude",
            "LongQuat",
            r"returned quat at user 0, sample 0: \[.*\], "
            + _RULE
            + r"unit length: \| \|q\| - 1 \| <= 0\.001",
        ),
        (
            "steps",
            "FutureStep",
            r"returned peak_time at user 0, sample 9: \[0\.59, nan\], "
            + _RULE
            + r"on the stream's own clock .* no step before the reset or from the future",
        ),
        (
            "steps",
            "NegativeSteps",
            r"returned steps at user 0, sample 0: -1, " + _RULE + r"an integer 0, 1 or 2",
        ),
        (
            "hand",
            "PitchHand",
            r"returned ypr at user 0, frame 0: \[[-.\d]+, 4, [-.\d]+\], "
            + _RULE
            + r"every angle in \[-pi, pi\] where finite",
        ),
        (
            "hand",
            "NanHand",
            r"returned ypr at user 0, frame 0: \[nan, nan, nan\], "
            + _RULE
            + r"finite where `valid` is True",
        ),
        ("steering", "NanSteering", r"returned yaw at user 0: nan, " + _RULE + r"finite"),
        (
            "locomotion",
            "FarAway",
            r"returned position at user 0: \[1e\+09, 1e\+09\], "
            + _RULE
            + r"within 10000 m of the room's origin",
        ),
        ("locomotion", "LostHeading", r"returned heading at user 0: nan, " + _RULE + r"finite"),
    ],
)
def test_a_plugin_output_without_meaning_names_stage_plugin_value_and_rule(
    toys, field, toy, message
):
    """Each toy's output has the right shape but breaks one rule of its stage's contract: the
    error names the stage, the plug-in, the first offending user and sample and its value, and
    states the rule."""
    env = gym.make("VRLoco-Interact-v0", estimators=EstimatorConfig(**{field: f"{toys}:{toy}"}))
    assert isinstance(getattr(env.unwrapped.core.users.stages, field), CheckedStage)
    with pytest.raises(StageError, match=rf"^{field} plug-in '.*toys\.py:{toy}' {message}"):
        _steps_until_error(env)
    env.close()


def test_plugins_inside_the_rules_run_and_their_outputs_reach_the_env(toys):
    """Quaternions 1.0009 long (inside the stated tolerance) pass through unchanged: the same
    estimated attitude as the EKF they scale. A step at every chunk's last sample, its heel
    strike right there (on the stream's clock, reset with the episode): one step per control
    step, episode after episode."""
    scaled = gym.make(
        "VRLoco-Approach-v0", estimators=EstimatorConfig(attitude=f"{toys}:AlmostUnitQuat")
    )
    plain = gym.make("VRLoco-Approach-v0")
    for env in (scaled, plain):
        env.reset(seed=0)
    for _ in range(20):
        ypr_scaled, ypr_plain = (env.step(WALK)[-1]["est_ypr"] for env in (scaled, plain))
        np.testing.assert_allclose(ypr_scaled, ypr_plain, atol=0.1)  # deg
    env = gym.make("VRLoco-Approach-v0", estimators=EstimatorConfig(steps=f"{toys}:StepAtEnd"))
    for seed in (0, 1):
        env.reset(seed=seed)
        assert [env.step(WALK)[-1]["detected_steps"] for _ in range(20)] == [1] * 20


def test_a_step_plugin_that_ignores_reset_reports_steps_from_the_future(toys):
    """The proxy keeps each user's clock since its reset: a detector whose clock runs on through
    the reset reports, in the second episode, heel strikes the new stream has not lived yet."""
    env = gym.make(
        "VRLoco-Approach-v0", estimators=EstimatorConfig(steps=f"{toys}:ClockNeverResets")
    )
    _steps_until_error(env, steps=10)  # the first episode: both clocks agree
    with pytest.raises(StageError, match=r"peak_time at user 0, sample 9: \[1\.09, nan\].*future"):
        _steps_until_error(env, steps=1)
    env.close()


def test_only_plugins_are_wrapped_and_each_once():
    """The package's own stages are used as built (the golden episodes' speed and bits); a
    plug-in is wrapped once, and reads through to the plug-in's attributes."""
    users = gym.make("VRLoco-Approach-v0").unwrapped.core.users
    for field in ("attitude", "steps", "hand", "steering", "locomotion"):
        assert not isinstance(getattr(users.stages, field), CheckedStage)
        assert users.stages.trusted[field]
    cfg = EstimatorConfig(
        attitude="estimators.attitude:EkfStage", steps=stages.STEPS.factory("zhang2021")
    )
    users = gym.make("VRLoco-Approach-v0", estimators=cfg).unwrapped.core.users
    for field, inner in (("attitude", "EkfStage"), ("steps", "Zhang2021Steps")):
        stage = getattr(users.stages, field)
        assert isinstance(stage, CheckedStage) and type(stage.wrapped).__name__ == inner
        assert not users.stages.trusted[field]
    assert users.attitude is users.stages.attitude and users.gait is users.stages.steps
    assert users.gait.report_delay_s == users.gait.wrapped.report_delay_s > 0
    assert not isinstance(users.hand_filter, CheckedStage)
    copied = pickle.loads(pickle.dumps(users.stages))  # as a process pool would send them
    assert type(copied.attitude.wrapped).__name__ == "EkfStage"


_EVERY_NAME = [
    (f, n)
    for f in ("attitude", "steps", "hand", "steering", "locomotion")
    for n in getattr(stages, f.upper()).names()
]


@pytest.mark.parametrize(("field", "name"), _EVERY_NAME)
def test_the_package_s_stages_behind_the_proxy_break_no_rule_and_change_nothing(
    field, name, monkeypatch
):
    """Every registered stage, wrapped as a plug-in would be, runs two episodes of a walking,
    hand-turning user without breaking a rule, and gives the same episodes to the bit: the
    rules are no stricter than the package's own estimators, and the proxy changes nothing."""
    cfg = EstimatorConfig(**{field: name})
    plain = gym.make("VRLoco-Interact-v0", estimators=cfg)
    expected = _walking_episode(plain, 3) + _walking_episode(plain, 4)
    monkeypatch.setattr(pipeline, "_is_ours", lambda spec, registry: False)
    wrapped = gym.make("VRLoco-Interact-v0", estimators=cfg)
    assert isinstance(wrapped.unwrapped.core.users.stages.hand, CheckedStage)
    got = _walking_episode(wrapped, 3) + _walking_episode(wrapped, 4)
    assert len(got) == len(expected)
    for k, (a, b) in enumerate(zip(got, expected, strict=True)):
        np.testing.assert_array_equal(a, b, err_msg=f"value {k}")


class _NoTakeSteering:
    def __init__(self, batch_size):
        pass

    def reset(self, rows=None):
        pass

    def update(self, head_yaw, torso_yaw, torso_valid):
        return head_yaw


def test_a_batch_of_wrapped_stages_sheds_users_as_the_whole_batch_goes_on(monkeypatch):
    """Wrapped stages drop users through the proxy (its step clocks too): the kept users go on
    as in the whole batch, through a reset of one of them, and nothing stays B long. A plug-in
    without take_users makes the batch unable to shed users, as before."""
    b, rows = 7, np.array([5, 0, 3])  # 7: no size of the rest of the env is B by chance

    def make(**kw):
        return VRLocoVectorEnv(
            b, task="approach", technique="nod_robust", autoreset_mode=AutoresetMode.DISABLED, **kw
        )

    whole = make()
    monkeypatch.setattr(pipeline, "_is_ours", lambda spec, registry: False)
    kept = make()
    assert isinstance(kept.core.users.gait, CheckedStage) and kept.can_take_users
    actions = np.random.default_rng(5).uniform(0.2, 1.0, (50, b, 5)).astype(np.float32)
    whole.reset(seed=list(range(b)))
    kept.reset(seed=list(range(b)))
    for t in range(50):
        if t == 15:
            kept.take_users(rows)
            left = [p for p in sized(kept, b) if ".layouts[" not in p and ".layout." not in p]
            assert not left, left
        if t == 30:  # whole row 0 is kept row 1
            whole.reset(seed=[100, *[None] * (b - 1)], options={"reset_mask": np.arange(b) == 0})
            kept.reset(seed=[None, 100, None], options={"reset_mask": np.arange(3) == 1})
        out_w = whole.step(actions[t])
        out_k = kept.step(actions[t][rows] if t >= 15 else actions[t])
        sel = rows if t >= 15 else slice(None)
        for w, k in zip(out_w[:4], out_k[:4], strict=True):
            np.testing.assert_array_equal(w[sel], k, err_msg=f"step {t}")
        np.testing.assert_array_equal(
            out_w[4]["detected_step_times"][sel], out_k[4]["detected_step_times"]
        )
    stuck = VRLocoVectorEnv(
        2,
        task="approach",
        autoreset_mode=AutoresetMode.DISABLED,
        estimators=EstimatorConfig(steering=_NoTakeSteering),
    )
    assert not hasattr(stuck.core.users.steering, "take_users") and not stuck.can_take_users


# ------------------------------------------------------------------------------ protocol members
class _HalfLocomotion:
    def __init__(self, batch_size, step_length):
        pass

    def reset(self, mask=None, position=None, heading=None):
        pass

    def update(self, steps, yaw, dt):
        return np.zeros((np.size(steps), 2))


class _RowsLocomotion(_HalfLocomotion):
    batch_size, position, heading, distance = 1, np.zeros((1, 2)), np.zeros(1), np.zeros(1)

    def reset(self, rows=None):
        pass


def test_missing_members_are_named_from_the_protocol_itself():
    """A plug-in missing members of its protocol gets them named, on Python 3.11 as on 3.12
    (the members are read from the protocol class, not from 3.12's ``__protocol_attrs__``)."""
    with pytest.raises(
        StageError,
        match=r"locomotion plug-in '_HalfLocomotion' built a "
        r"_HalfLocomotion, which lacks batch_size, position, heading, distance of "
        r"the Locomotion protocol",
    ):
        gym.make("VRLoco-Approach-v0", estimators=EstimatorConfig(locomotion=_HalfLocomotion))
    assert protocol_members(Locomotion) == [
        "batch_size",
        "update",
        "reset",
        "position",
        "heading",
        "distance",
    ]
    for registry in (stages.ATTITUDE, stages.STEPS, stages.HAND, stages.STEERING):
        assert protocol_members(registry.protocol) == ["reset", "update"]

    from typing import Protocol

    class Base(Protocol):
        size: int

        def grow(self, by: int) -> None: ...

    class Child(Base, Protocol):
        @property
        def area(self) -> float: ...

    assert protocol_members(Child) == ["size", "grow", "area"]
    if sys.version_info >= (3, 12):  # where Python lists them itself, the lists agree
        assert set(protocol_members(Child)) == set(Child.__protocol_attrs__)


def test_a_method_that_cannot_take_the_environment_s_call_is_named():
    """``reset(rows=None)`` for a locomotion stage, which the environment resets with
    ``reset(mask, position=..., heading=...)``: an error at ``gym.make``, not a TypeError at
    ``env.reset``."""
    with pytest.raises(
        StageError,
        match=r"has reset\(rows=None\), which cannot be called as "
        r"reset\(mask, position=\.\.\., heading=\.\.\.\)",
    ):
        gym.make("VRLoco-Approach-v0", estimators=EstimatorConfig(locomotion=_RowsLocomotion))


# ------------------------------------------------------------------------------ reference
REPO = Path(__file__).resolve().parents[2]
REGENERATE = ".venv/bin/python -m estimators.stage_docs > docs/protocols.md"


def test_docs_protocols_md_is_the_generated_reference():
    """docs/protocols.md is what the generator renders from the protocols and the checks."""
    doc = (REPO / "docs" / "protocols.md").read_text()
    assert doc == stage_docs.protocol_reference(), f"docs/protocols.md is stale: run `{REGENERATE}`"


def test_the_reference_states_every_member_call_and_rule_that_is_checked():
    """Everything the build check and the proxy enforce appears in the reference: each
    protocol member, each call form, each output's shape and each rule's text; and the command
    it names regenerates it."""
    import subprocess

    doc = stage_docs.protocol_reference()
    for registry in (
        stages.ATTITUDE,
        stages.STEPS,
        stages.HAND,
        stages.STEERING,
        stages.LOCOMOTION,
    ):
        section = doc.split(f"## `{registry.stage}`")[1].split("\n## ")[0]
        for name in protocol_members(registry.protocol):
            assert f"- `{name}" in section, (registry.stage, name)
        for method, (positional, keywords) in registry.contract.calls.items():
            call = ", ".join([*positional, *(f"{k}=..." for k in keywords)])
            assert f"called as `{method}({call})`" in section, (registry.stage, method)
        for out in registry.contract.outputs:
            assert f"| `{out.name}` | ({', '.join(map(str, out.shape))}" in section
        for rule in registry.contract.rules:
            assert rule.text.replace("|", "\\|") in section, (registry.stage, rule.text)
    run = subprocess.run(
        [sys.executable, "-m", "estimators.stage_docs"],
        cwd=REPO,
        capture_output=True,
        text=True,
        check=True,
    )
    assert run.stdout == doc


# ------------------------------------------------------------------------------ techniques
def test_the_default_env_is_the_zhang2021_technique_bit_for_bit():
    a = _episode(gym.make("VRLoco-Approach-v0"))
    b = _episode(gym.make("VRLoco-Approach-v0", technique="zhang2021"))
    np.testing.assert_array_equal(a, b)
    assert gym.make("VRLoco-Approach-v0").unwrapped.technique == "zhang2021"


@pytest.mark.parametrize("name", ["smooth", "torso_steering", "zhang2021_as_printed"])
def test_a_technique_equals_its_estimator_config(name):
    tech = TECHNIQUES[name]
    a = _episode(gym.make("VRLoco-Avoid-v0", technique=name))
    b = _episode(
        gym.make("VRLoco-Avoid-v0", estimators=tech.estimators, sensor_preset=tech.sensor_preset)
    )
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, _episode(gym.make("VRLoco-Avoid-v0")))  # and it changes things


def test_the_consumer_technique_is_the_consumer_preset():
    env = gym.make("VRLoco-Approach-v0", technique="zhang2021_consumer")
    assert env.unwrapped.sensors.preset_name == "consumer_mems"
    assert env.unwrapped.technique == "zhang2021_consumer"
    shorthand = gym.make("VRLoco-Approach-v0", sensor_preset="consumer_mems")
    assert shorthand.unwrapped.technique == "zhang2021_consumer"
    np.testing.assert_array_equal(_episode(env), _episode(shorthand))


def test_an_unregistered_technique_object_and_the_vector_env():
    tech = Technique(
        "mine", "smooth on consumer", "consumer_mems", EstimatorConfig(locomotion="smooth")
    )
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
        ({"technique": "zhang2021", "sensor_preset": "consumer_mems"}, "contradicts technique"),
        (
            {"technique": "zhang2021_consumer", "sensors": SensorConfig(imu="ig500n")},
            "sensors.imu='ig500n' contradicts technique='zhang2021_consumer'",
        ),
        (
            {"sensors": SensorConfig(imu="ig500n"), "technique": "zhang2021_consumer"},
            "sensors.imu='ig500n' contradicts technique='zhang2021_consumer'",
        ),
        ({"technique": "zhang2021_consumer", "sensors": SensorConfig(imu_rate_hz=200.0)}, None),
        ({"technique": "smooth", "locomotion": "eq17"}, "locomotion='eq17' contradicts"),
        (
            {"sensors": SensorConfig(imu="consumer_mems"), "sensor_preset": "ig500n"},
            "sensor_preset='ig500n' contradicts",
        ),
        ({"technique": "nope"}, "technique='nope': unknown; valid names: zhang2021"),
        (
            {"config": EnvConfig(motion=MotionParams(imu_rate_hz=200.0))},
            "MotionParams.imu_rate_hz=200.0 contradicts SensorConfig.imu_rate_hz",
        ),
    ],
)
def test_contradicting_arguments_are_an_error(kwargs, message):
    if message is None:  # a SensorConfig naming no IMU takes the technique's, keeping the rest
        env = gym.make("VRLoco-Approach-v0", **kwargs)
        assert env.unwrapped.sensors.preset_name == "consumer_mems"
        assert env.unwrapped.sensors.imu_rate_hz == kwargs["sensors"].imu_rate_hz
        return
    with pytest.raises(ValueError, match=message):
        gym.make("VRLoco-Approach-v0", **kwargs)


def test_motion_params_follow_the_sensors_without_overwriting_a_choice():
    env = gym.make("VRLoco-Approach-v0", sensors=SensorConfig(imu_rate_hz=200.0))
    assert env.unwrapped.core.users.motion_params.imu_rate_hz == 200.0
    env = gym.make(
        "VRLoco-Approach-v0",
        sensors=SensorConfig(imu_rate_hz=200.0),
        config=EnvConfig(motion=MotionParams(imu_rate_hz=200.0)),
    )
    assert env.unwrapped.core.users.motion_params.imu_rate_hz == 200.0


# ------------------------------------------------------------------------------ steering
def test_torso_steering_walks_straight_while_the_head_looks_around():
    """A user walks in place facing +x while scanning +-35 deg left and right (head on torso).
    Head steering walks where the head looks; torso steering follows the shoulders."""
    from vrloco_env.core import LocoCore
    from vrloco_env.env import make_configs
    from vrloco_env.user import Intent

    headings = {}
    for name in ("zhang2021", "torso_steering"):
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
                cadence=np.full(3, 1.8),
                turn_rate=np.zeros(3),
                hand_rates=np.zeros((3, 3)),
                gesture_amplitude=np.tile([np.deg2rad(35.0), 0.0, 0.0], (3, 1)),
                gesture_frequency=np.tile([0.3, 0.3, 0.3], (3, 1)),
                lean=np.zeros(3),
            )
            position = position + users.step(intent).displacement
            positions.append(position)
        path = np.diff(np.array(positions), axis=0)  # (T, B, 2)
        moving = np.hypot(path[..., 0], path[..., 1]) > 1e-6
        direction = np.arctan2(path[..., 1], path[..., 0])
        err = np.rad2deg(np.angle(np.exp(1j * (direction - start_yaw))))[moving]
        headings[name] = np.sqrt(np.mean(err**2))
    # The head sweeps +-35 deg: the walk follows it (RMS ~ 35 / sqrt 2 = 25 deg) ...
    assert headings["zhang2021"] > 15.0
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
