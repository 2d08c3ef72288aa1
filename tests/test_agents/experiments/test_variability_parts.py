"""Each part of a population on its own: the conditions switch on exactly their part, and the
two ends reproduce the benchmark's plain and ``+population`` users."""

import pytest

from agents.benchmark.variability import VariabilityParams
from agents.experiments.variability_parts import (
    CONDITIONS,
    PARTS,
    condition_params,
    variability_parts,
)


def test_each_condition_switches_on_its_part_alone():
    full = VariabilityParams.from_population("nodders")
    assert condition_params("nodders", "idealised") == (False, None)
    assert condition_params("nodders", "head") == (True, None)
    assert condition_params("nodders", "population") == (True, full)
    assert condition_params("nodders", "variability") == (False, full)
    for part, names in PARTS.items():
        head, params = condition_params("nodders", part)
        assert not head
        for other, fields in PARTS.items():
            for f in fields:
                want = getattr(full, f) if other == part else 0.0
                assert getattr(params, f) == want, (part, f)
        assert any(getattr(full, f) > 0.0 for f in names)  # the part is switched on at all


def test_the_ends_reproduce_the_benchmark_users():
    from agents.benchmark import run_benchmark

    r = variability_parts(
        "reach", "nodders", episodes=3, seed=2000, conditions=("idealised", "population")
    )
    rows = run_benchmark(
        tasks=["reach"],
        policies=["goal_seeker", "goal_seeker+nodders"],
        techniques=["zhang2021"],
        episodes=3,
        seed=2000,
        workers=1,
        progress=False,
        print_table=False,
    )
    for row, condition in zip(rows, ("idealised", "population"), strict=True):
        c = r["conditions"][condition]
        assert c["collision_free_success"] == round(3 * row["collision_free_success_rate"])
        assert c["success"] == round(3 * row["success_rate"])
        assert c["episodes_colliding"] == round(3 * row["collision_rate"])
        assert sum(c["first_walked_into"].values()) == c["episodes_colliding"]


def test_bad_settings_are_named():
    with pytest.raises(ValueError, match="episodes=0: must be >= 1"):
        variability_parts("reach", "nodders", episodes=0, seed=0)
    with pytest.raises(ValueError, match="give the policy alone"):
        variability_parts("reach", "nodders", episodes=1, seed=0, policy="goal_seeker+typical")
    with pytest.raises(ValueError, match="choose from " + ", ".join(CONDITIONS)):
        variability_parts("reach", "nodders", episodes=1, seed=0, conditions=("nodding",))
    with pytest.raises(ValueError, match="nobody"):
        variability_parts("reach", "nobody", episodes=1, seed=0)
