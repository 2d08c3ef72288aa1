"""Names after the papers' authors: the earlier seed-numbered names still work for one release,
each with a DeprecationWarning, and give exactly what the new names give."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import vrloco_env  # noqa: F401
from estimators.stages import HAND, STEPS
from vrloco_env.config import EstimatorConfig
from vrloco_env.techniques import RENAMED, TECHNIQUES, get_technique


def test_listings_show_only_the_new_names():
    assert not set(RENAMED) & set(TECHNIQUES)
    assert set(RENAMED.values()) <= set(TECHNIQUES)
    assert "seed000" not in STEPS.names() and "zhang2021" in STEPS.names()
    assert "seed003" not in HAND.names() and "yao2023" in HAND.names()


@pytest.mark.parametrize(("old", "new"), sorted(RENAMED.items()))
def test_an_old_technique_name_warns_and_runs_the_new_technique(old, new):
    with pytest.warns(DeprecationWarning, match=f"technique '{old}' is now called '{new}'"):
        assert get_technique(old) is TECHNIQUES[new]
    with pytest.warns(DeprecationWarning):
        env_old = gym.make("VRLoco-Approach-v0", technique=old)
    env_new = gym.make("VRLoco-Approach-v0", technique=new)
    assert env_old.unwrapped.technique == new
    acts = np.tile(np.array([0.8, 0.1, 0.0, 0.0, 0.0], np.float32), (20, 1))
    for env in (env_old, env_new):
        env.reset(seed=3)
    for a in acts:
        o1, r1, *_ = env_old.step(a)
        o2, r2, *_ = env_new.step(a)
        np.testing.assert_array_equal(o1, o2)
        assert r1 == r2


@pytest.mark.parametrize(
    ("field", "old", "new"), [("steps", "seed000", "zhang2021"), ("hand", "seed003", "yao2023")]
)
def test_an_old_stage_name_warns_and_becomes_the_new_one(field, old, new):
    with pytest.warns(DeprecationWarning, match=f"'{old}' is now called '{new}'"):
        config = EstimatorConfig(**{field: old})
    assert getattr(config, field) == new
    assert config == EstimatorConfig()


def test_old_class_names_import_with_a_warning():
    from estimators.hand import Yao2023Hand
    from estimators.steps import Zhang2021Steps

    with pytest.warns(DeprecationWarning, match="Seed000Steps is now called Zhang2021Steps"):
        from estimators.steps import Seed000Steps
    with pytest.warns(DeprecationWarning, match="Seed003Hand is now called Yao2023Hand"):
        from estimators.hand import Seed003Hand
    assert Seed000Steps is Zhang2021Steps and Seed003Hand is Yao2023Hand
    with pytest.raises(ImportError, match="cannot import name 'Seed999'"):
        from estimators.steps import Seed999  # noqa: F401


def test_the_benchmark_reports_an_old_name_under_the_new_one():
    from agents.benchmark.grid import Grid

    with pytest.warns(DeprecationWarning):
        grid = Grid(("approach",), ("goal_seeker",), ("seed000", "vqf"))
    assert grid.techniques == ("zhang2021", "vqf")
