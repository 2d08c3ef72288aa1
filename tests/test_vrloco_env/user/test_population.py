"""User populations: the registry, its errors, the per-user draws and the policy suffix."""

from dataclasses import replace

import gymnasium as gym
import numpy as np
import pytest

import vrloco_env  # noqa: F401  (registers the ids)
from agents.benchmark.policies import build_policy, check_policy
from agents.benchmark.variability import HumanVariability, VariabilityParams
from vrloco_env.batch_rng import BatchRng
from vrloco_env.config import EnvConfig
from vrloco_env.user.behaviour import GazeBehaviour
from vrloco_env.user.population import POPULATIONS, RANGE_FIELDS, Population, get_population


def test_unknown_population_names_the_field_and_the_choices():
    with pytest.raises(
        ValueError,
        match=r"EnvConfig.population='walkers': unknown; valid names: "
        r"idealised, human, typical, gaze_scanners, nodders",
    ):
        EnvConfig(population="walkers")
    with pytest.raises(ValueError, match="population='walkers'"):
        gym.make("VRLoco-Approach-v0", population="walkers")
    with pytest.raises(ValueError, match="population=3"):
        get_population(3)


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [
        ("nod_frequency_hz", (3.0, 1.0), r"Population.nod_frequency_hz=\(3.0, 1.0\)"),
        ("eye_range_deg", (10.0, 60.0), r"Population.eye_range_deg=.*\[0, 45\] deg"),
        ("scan_rate_hz", (-0.1, 0.2), r"Population.scan_rate_hz"),
        ("max_head_yaw_deg", 95.0, r"Population.max_head_yaw_deg=95.0.*\[0, 80\] deg"),
        ("gaze", 1, r"Population.gaze=1: must be True or False"),
        ("bob_scale", (1.0,), r"Population.bob_scale"),
    ],
)
def test_impossible_populations_are_rejected_naming_field_and_range(field, value, match):
    with pytest.raises(ValueError, match=match):
        replace(POPULATIONS["typical"], **{field: value})


def test_each_user_draws_its_own_values_within_the_ranges_reproducibly():
    pop = POPULATIONS["typical"]

    def draw(seeds):
        g = GazeBehaviour(pop, BatchRng.from_seeds(seeds), 0.1, np.zeros(3))
        g.reset()
        return g.values

    a, b = draw(range(50)), draw(range(50))
    for f in RANGE_FIELDS:
        lo, hi = getattr(pop, f)
        np.testing.assert_array_equal(a[f], b[f])  # same seeds, same users
        assert np.all((a[f] >= lo) & (a[f] <= hi)), f
        if hi > lo:  # spread over the range (50 uniform draws cover most of it)
            assert np.ptp(a[f]) > 0.6 * (hi - lo), f
    # one user in a batch draws what it draws alone
    single = draw([17])
    batch = draw([3, 17])
    for f in RANGE_FIELDS:
        assert batch[f][1] == single[f][0]


def test_bob_scale_scales_the_vertical_head_acceleration_of_steps():
    heavy = Population("heavy", "", bob_scale=(1.5, 1.5))

    def peak(pop):
        env = gym.make("VRLoco-Approach-v0", population=pop, max_episode_steps=30)
        env.reset(seed=2)
        acc = []
        for _ in range(30):
            env.step(np.array([0.5, 0, 0, 0, 0], np.float32))
            acc.append(env.unwrapped.core.last.motion.acc[0, :, 2])
        return np.abs(np.concatenate(acc)).max()

    # the bob scales; the IMU's small vertical motion from the sway's head roll does not
    assert peak(heavy) / peak(None) == pytest.approx(1.5, rel=0.002)


def test_plus_human_is_todays_variability_and_other_suffixes_are_populations():
    env = gym.make("VRLoco-Approach-v0")
    human = build_policy("goal_seeker+human", env)
    assert isinstance(human, HumanVariability) and human.name == "goal_seeker+human"
    assert human.params == VariabilityParams()
    assert VariabilityParams.from_population("human") == VariabilityParams()
    typical = build_policy("goal_seeker+typical", env)
    assert typical.name == "goal_seeker+typical"
    pop = POPULATIONS["typical"]
    assert typical.params.reaction_delay_s == pop.reaction_delay_s
    assert typical.params.cadence_bias_sd == pop.cadence_bias_sd
    assert not isinstance(build_policy("goal_seeker+idealised", env), HumanVariability)
    assert check_policy("goal_seeker+nodders") == "goal_seeker+nodders"
    with pytest.raises(
        ValueError,
        match=r"unknown population 'robots' after '\+'; valid names: "
        r"idealised, human, typical",
    ):
        check_policy("goal_seeker+robots")


def test_the_goal_seeker_reaches_the_goal_while_its_head_looks_around():
    """With gaze the view turns with the head; the seeker aims its body by the observed
    head-on-torso yaw and still walks to the goal."""
    env = gym.make("VRLoco-Approach-v0", population="typical")
    policy = build_policy("goal_seeker", env)
    obs, _ = env.reset(seed=3)
    policy.reset(np.random.default_rng(0))
    heads = []
    while True:
        obs, _, te, tr, info = env.step(policy.act(obs))
        heads.append(abs(env.unwrapped.core.last.motion.head_on_torso_yaw[0, -1]))
        if te or tr:
            break
    assert info["is_success"] and info["collisions"] == 0
    assert np.rad2deg(max(heads)) > 30.0  # the head did turn away from the body
