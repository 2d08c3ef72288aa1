"""Technique-adapted users: a seeded fine-tune of the shipped user per cell, cached, and the
``ppo@STEPS`` spec and ``--adapt`` that play them."""

import pytest

from agents.learned import train_ppo  # noqa: F401  (before torch: see agents.learned)
from agents.learned.adapt import adapted_user


def test_an_adapted_user_is_trained_once_per_cell_and_budget_and_a_damaged_one_again(
    tmp_path, capsys
):
    from agents.benchmark.policies import load_ppo
    from agents.learned.users import shipped_user

    assert (
        adapted_user("avoid", "smooth", steps=0, cache_dir=tmp_path) == shipped_user("avoid").path
    )
    path = adapted_user("avoid", "smooth", steps=1024, cache_dir=tmp_path, num_envs=4)
    model = load_ppo(path)
    assert model.vrloco_cell["technique"] == "smooth" and model.num_timesteps > 0
    stamp = path.stat().st_mtime_ns
    assert adapted_user("avoid", "smooth", steps=1024, cache_dir=tmp_path, num_envs=4) == path
    assert path.stat().st_mtime_ns == stamp  # reused, not trained again
    other = adapted_user("avoid", "zhang2021", steps=1024, cache_dir=tmp_path, num_envs=4)
    assert other != path  # another cell, another user
    human = adapted_user(
        "avoid", "smooth", steps=1024, cache_dir=tmp_path, num_envs=4, variability="typical"
    )
    assert human != path and load_ppo(human).vrloco_variability == "typical"
    path.write_bytes(b"not a zip")
    again = adapted_user("avoid", "smooth", steps=1024, cache_dir=tmp_path, num_envs=4)
    assert again == path and load_ppo(again).vrloco_cell["technique"] == "smooth"
    assert "is damaged" in capsys.readouterr().out


def test_bad_budgets_and_cells_are_named(monkeypatch):
    from agents.benchmark.policies import adapt_seed, adapt_steps, check_policy
    from agents.learned import users

    monkeypatch.delitem(users.LEARNED_USERS, "interact")

    with pytest.raises(ValueError, match=r"steps=-1: must be an integer >= 0"):
        adapted_user("avoid", steps=-1)
    with pytest.raises(ValueError, match=r"no learned user is shipped for task 'interact'"):
        adapted_user("interact", steps=10)
    with pytest.raises(ValueError, match=r"write ppo@STEPS"):
        check_policy("ppo@many")
    assert adapt_steps("ppo@300+typical") == 300 and adapt_steps("ppo") == 0
    assert adapt_seed("ppo@300:7+typical") == 7 and adapt_seed("ppo@300") == 0
    assert adapt_steps("ppo@300:7") == 300
    for bad in ("ppo@300:", "ppo@300:x", "ppo@:7"):
        with pytest.raises(ValueError, match=r"write ppo@STEPS or ppo@STEPS:SEED"):
            check_policy(bad)


def test_the_spec_s_seed_is_the_fine_tuning_s(monkeypatch):
    import gymnasium as gym

    from agents.benchmark.policies import build_policy
    from agents.learned.users import shipped_user

    asked = []

    def fake_adapted_user(task, technique, population, condition, steps, seed=0, **kw):
        asked.append((task, steps, seed))
        return shipped_user(task).path

    monkeypatch.setattr("agents.learned.adapt.adapted_user", fake_adapted_user)
    env = gym.make("VRLoco-Avoid-v0")
    for spec in ("ppo@500:3+typical", "ppo@500"):
        build_policy(spec, env)
    env.close()
    assert asked == [("avoid", 500, 3), ("avoid", 500, 0)]


def test_adapt_needs_the_shipped_user_among_the_policies(capsys):
    from agents.cli import main

    assert main(["benchmark", "--policies", "goal_seeker", "--adapt", "100"]) == 2
    assert "--adapt needs --policies ppo" in capsys.readouterr().err


def test_an_adapted_user_has_the_same_weights_whatever_torch_s_thread_count(tmp_path):
    import os

    import torch

    from agents.benchmark.policies import load_ppo

    if (os.cpu_count() or 1) < 2:
        pytest.skip("one core: torch has no second thread to sum with")
    before = torch.get_num_threads()
    weights = []
    try:
        for threads in (2, 1):
            torch.set_num_threads(threads)
            path = adapted_user(
                "avoid", "smooth", steps=1024, cache_dir=tmp_path / str(threads), num_envs=4
            )
            assert torch.get_num_threads() == threads  # given back after the fine-tuning
            weights.append(load_ppo(path).policy.state_dict())
    finally:
        torch.set_num_threads(before)
    assert weights[0].keys() == weights[1].keys()
    for name, value in weights[0].items():
        assert torch.equal(value, weights[1][name]), name
