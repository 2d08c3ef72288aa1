"""Physical-room conditions: the magnetometer reads the condition's dipole, the default changes
nothing, and the benchmark compares techniques within a condition."""

import gymnasium as gym
import numpy as np
import pytest

import vrloco_env  # noqa: F401  (registers the ids)
from agents.benchmark import run_benchmark, step_window
from agents.benchmark.conditions import CONDITIONS, Condition, get_condition
from agents.benchmark.episodes import run_cell_episode
from agents.benchmark.grid import Cell
from agents.benchmark.paired import episode_values, paired_p_values
from agents.benchmark.resume import episode_key
from vrloco_env.sensors.imu import MU0_OVER_4PI, EarthField
from vrloco_env.techniques import get_technique


def test_unknown_conditions_are_named():
    with pytest.raises(ValueError, match=r"condition=.kitchen.*lab, beside_metal"):
        get_condition("kitchen")
    with pytest.raises(ValueError, match="conditions='kitchen'"):
        run_benchmark(
            tasks=["approach"],
            policies=["goal_seeker"],
            techniques=["zhang2021"],
            episodes=1,
            conditions=["kitchen"],
            progress=False,
            print_table=False,
        )
    with pytest.raises(ValueError, match=r"Condition.magnetic_disturbances=.*MagneticDisturbance"):
        Condition("odd", "not a dipole", (1.0,))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="conditions must not repeat"):
        run_benchmark(
            tasks=["approach"],
            policies=["goal_seeker"],
            techniques=["zhang2021"],
            episodes=1,
            conditions=["lab", "lab"],
            progress=False,
            print_table=False,
        )


def test_the_default_condition_is_the_plain_env():
    """``lab`` passes no sensors: the episode, its resume key and its file names are what they
    are without a condition."""
    assert get_condition("lab").sensors() is None
    cell = Cell("approach", "goal_seeker")
    assert cell.condition == "lab" and cell.label == "approach_goal_seeker_zhang2021"
    tech = get_technique("zhang2021")
    assert episode_key("fp", "approach", "goal_seeker", tech, 3, False) == episode_key(
        "fp", "approach", "goal_seeker", tech, 3, False, "lab"
    )
    assert episode_key("fp", "approach", "goal_seeker", tech, 3, False) != episode_key(
        "fp", "approach", "goal_seeker", tech, 3, False, "beside_metal"
    )


def test_beside_metal_adds_the_dipole_field_the_closed_form_gives():
    """The cabinet's field at the start spot's head height, from the dipole formula
    ``B = mu0/4pi (3 r (m.r)/|r|^5 - m/|r|^3)``, is what the env's magnetometer model adds."""
    (dipole,) = CONDITIONS["beside_metal"].magnetic_disturbances
    head = np.array([0.0, 0.0, 1.6])
    r = head - np.asarray(dipole.position)
    m = np.asarray(dipole.moment)
    d = np.linalg.norm(r)
    want = MU0_OVER_4PI * (3 * r * (m @ r) / d**5 - m / d**3) * 1e6  # T -> uT
    np.testing.assert_allclose(dipole.field_at(head[None])[0], want, rtol=1e-12)
    assert 2.0 < np.linalg.norm(want) < 10.0  # a few uT: a fifth of the horizontal field or less
    env = gym.make("VRLoco-Approach-v0", sensors=get_condition("beside_metal").sensors())
    assert env.unwrapped.sensors.magnetic_disturbances == (dipole,)
    env.close()


def test_the_trolley_passes_along_the_cabinets_line_while_the_user_walks():
    """The trolley is the cabinet's dipole, 3 m to one side until 2 s, abreast of the start spot
    at 5 s, 3 m to the other side from 8 s; its field at the head peaks abreast of it."""
    (cabinet,) = CONDITIONS["beside_metal"].magnetic_disturbances
    (trolley,) = CONDITIONS["trolley_passing"].magnetic_disturbances
    assert trolley.moment == cabinet.moment
    for t, x in ((0.0, -3.0), (2.0, -3.0), (5.0, 0.0), (8.0, 3.0), (30.0, 3.0)):
        np.testing.assert_allclose(trolley.position_at(t), (x, 1.3, 1.0), atol=1e-12)
    head = np.array([0.0, 0.0, 1.6])
    times = np.linspace(0.0, 10.0, 101)
    field = np.linalg.norm(trolley.field_at(np.tile(head, (101, 1)), times), axis=-1)
    assert times[np.argmax(field)] == pytest.approx(5.0)
    np.testing.assert_allclose(field.max(), np.linalg.norm(cabinet.field_at(head)), rtol=1e-12)
    assert field[0] < 0.2 * field.max()
    # at the head, the earth field plus the trolley's bends north by 3 deg over the pass, but
    # its norm changes by 0.5 % and its dip by 2.4 deg: within Zhang 2021's magnetometer gate
    # (10 %, 10 deg), which therefore never rejects it
    m = EarthField().vector_enu() + trolley.field_at(np.tile(head, (101, 1)), times)
    norm = np.linalg.norm(m, axis=1)
    dip = np.degrees(np.arcsin(-m[:, 2] / norm))
    north = np.degrees(np.arctan2(m[:, 0], m[:, 1]))
    assert np.ptp(north) == pytest.approx(3.0, abs=0.1)
    assert np.max(np.abs(norm / np.linalg.norm(EarthField().vector_enu()) - 1)) < 0.006
    assert np.max(np.abs(dip - dip[0])) == pytest.approx(2.4, abs=0.1)


def test_rows_compare_techniques_within_their_condition():
    kw = dict(
        tasks=["approach"],
        policies=["goal_seeker"],
        techniques=["zhang2021", "madgwick"],
        episodes=3,
        seed=5,
        conditions=["lab", "beside_metal"],
        progress=False,
        print_table=False,
        workers=1,
    )
    rows = run_benchmark(**kw)
    assert [(r["technique"], r["condition"]) for r in rows] == [
        ("zhang2021", "lab"),
        ("zhang2021", "beside_metal"),
        ("madgwick", "lab"),
        ("madgwick", "beside_metal"),
    ]
    ref = [
        run_cell_episode(Cell("approach", "goal_seeker", "zhang2021", "beside_metal"), s)
        for s in (5, 6, 7)
    ]
    own = [
        run_cell_episode(Cell("approach", "goal_seeker", "madgwick", "beside_metal"), s)[0]
        for s in (5, 6, 7)
    ]
    first = ref[0]
    late, early = step_window(first[1], first[0].elapsed_s / first[0].steps)
    ref = [stats for stats, _ in ref]
    want = paired_p_values(ref, own, late, early)["yaw_rate_mismatch_deg_s"]
    got = rows[3]["vs_baseline"]["yaw_rate_mismatch_deg_s"]
    assert got["n"] == want["n"] == 3
    assert got["p"] == pytest.approx(want["p"], rel=1e-6)
    truth = [
        episode_values(b, late, early)["yaw_rate_mismatch_deg_s"]
        - episode_values(a, late, early)["yaw_rate_mismatch_deg_s"]
        for a, b in zip(ref, own, strict=True)
    ]
    assert got["diff"] == pytest.approx(np.mean(truth), rel=1e-6)
    # the dipole changes the magnetometer, so the episodes differ between conditions
    lab = [run_cell_episode(Cell("approach", "goal_seeker", "madgwick"), s)[0] for s in (5, 6, 7)]
    assert any(
        not np.array_equal(a.heading_error_deg, b.heading_error_deg)
        for a, b in zip(lab, own, strict=True)
    )
