"""Training with a population's human variability: the learner sees what a person of that
population perceives, and its actions reach the body as that person's would."""

import numpy as np

from agents.learned import train_ppo  # before torch: see agents.learned
from agents.learned.variability_env import HumanVariabilityEnv
from vrloco_env.vector import VRLocoVectorEnv


def test_the_learner_sees_the_delayed_observation_and_the_body_gets_the_varied_action():
    from agents.benchmark.variability import HumanVariability, VariabilityParams

    n = 3
    env = HumanVariabilityEnv(VRLocoVectorEnv(n, task="avoid"), "typical", seed=5)
    raw = []  # the env's own observations, seen through a second, identical variability
    obs, _ = env.reset(seed=5)
    twin = HumanVariability(_Replay(), VariabilityParams.from_population("typical"), "typical")
    twin.reset([np.random.default_rng([5, 31, i, 0]) for i in range(n)])
    inner = env.env
    raw.append(inner.core.observe())
    np.testing.assert_array_equal(obs, twin.perceive(raw[-1]).astype(np.float32))
    rng = np.random.default_rng(0)
    delays = twin.delay_steps
    assert delays.max() >= 1  # the typical users react a few control steps late
    for _ in range(12):
        a = rng.uniform(-1, 1, (n, 5)).astype(np.float32)
        expected_body = twin.respond(a)
        obs, *_ = env.step(a)
        raw.append(inner.core.observe())
        np.testing.assert_array_equal(obs, twin.perceive(raw[-1]).astype(np.float32))
        assert not np.array_equal(expected_body, a)  # cadence and overshoot change the action
    for i in range(n):  # the learner's view is the observation of its delay ago
        np.testing.assert_array_equal(obs[i], raw[-1 - delays[i]][i])


class _Replay:
    def reset(self, rng=None, rows=None):
        pass

    def act(self, obs):
        raise AssertionError("the test acts outside")


def test_a_user_trains_with_a_populations_variability_and_the_model_says_so(tmp_path):
    path = train_ppo(
        "avoid",
        steps=1024,
        num_envs=4,
        out_dir=tmp_path,
        eval_every=1024,
        eval_episodes=2,
        progress=False,
        n_steps=256,
        batch_size=256,
        variability="typical",
    )
    from agents.benchmark.policies import load_ppo

    assert load_ppo(path).vrloco_variability == "typical"
