"""The simulated human's head: head-on-torso dynamics, gaze, nods, and what they do in the env."""

from dataclasses import replace

import gymnasium as gym
import numpy as np
import pytest

import vrloco_env  # noqa: F401  (registers the ids)
from vrloco_env.batch_rng import BatchRng
from vrloco_env.user import Intent, Joint, MotionParams, UserMotion
from vrloco_env.user.behaviour import GLANCE, GOAL, HAND, SCAN, GazeBehaviour
from vrloco_env.user.population import POPULATIONS, Population

DT = 0.1


def _head_run(target: float, steps: int = 15, lag: float = 0.1):
    motion = UserMotion(MotionParams(head_turn_lag_s=lag), BatchRng.from_seeds([3]))
    motion.reset(yaw=0.4)
    return [motion.advance(Intent(head_yaw=target)) for _ in range(steps)]


def test_the_head_turns_on_the_torso_with_main_sequence_dynamics():
    target, lag = np.deg2rad(40.0), 0.1
    chunks = _head_run(target, lag=lag)
    hot = np.concatenate([c.head_on_torso_yaw[0] for c in chunks])
    body = np.concatenate([c.body_yaw[0] for c in chunks])
    t = np.concatenate([c.t for c in chunks])
    np.testing.assert_allclose(body, 0.4)  # the torso does not turn with the head
    # critically damped: x(t) = A (1 - (1 + t / lag) e^(-t / lag)), no overshoot
    want = target * (1.0 - (1.0 + t / lag) * np.exp(-t / lag))
    np.testing.assert_allclose(hot, want, atol=1e-9)
    assert hot.max() <= target + 1e-12
    # its peak speed A / (e lag), 147 deg/s for 40 deg: inside the 100-300 deg/s of head
    # movements of that size; the body rate the IMU senses carries it
    omega_z = np.concatenate([c.omega[0, :, 2] for c in chunks])
    assert np.rad2deg(omega_z.max()) == pytest.approx(40.0 / (np.e * lag), rel=0.03)
    settle = t[np.argmax(hot > 0.95 * target)]
    assert 0.3 < settle < 0.6


def test_a_turned_head_moves_the_kinect_head_joint_not_the_shoulders():
    straight, turned = _head_run(0.0), _head_run(np.deg2rad(60.0))
    js, jt = straight[-1].kinect.joints[0, -1], turned[-1].kinect.joints[0, -1]
    for j in (Joint.SHOULDER_LEFT, Joint.SHOULDER_RIGHT, Joint.SPINE_MID, Joint.HAND_RIGHT):
        np.testing.assert_allclose(jt[j], js[j], atol=1e-12)
    # the head joint (2 cm in front of the neck pivot) now points 60 deg off the torso's yaw
    for joints, off in ((js, 0.0), (jt, 60.0)):
        v = joints[Joint.HEAD, :2] - joints[Joint.NECK, :2]
        assert np.rad2deg(np.arctan2(v[1], v[0]) - 0.4) == pytest.approx(off, abs=1e-3)  # settled


def test_head_yaw_outside_the_neck_range_is_rejected():
    motion = UserMotion(MotionParams(), BatchRng.from_seeds([0]))
    motion.reset()
    with pytest.raises(ValueError, match=r"Intent.head_yaw=.*must be in \[-1.396, 1.396\] rad"):
        motion.advance(Intent(head_yaw=1.5))
    with pytest.raises(ValueError, match=r"MotionParams\.head_turn_lag_s"):
        MotionParams(head_turn_lag_s=0.0)


def _behaviour(pop: Population, seeds, rays_range=5.0):
    rng = BatchRng.from_seeds(seeds)
    offsets = np.linspace(-np.pi / 2, np.pi / 2, 15)
    g = GazeBehaviour(pop, rng, DT, offsets)
    g.reset()
    return g, offsets


def _still(b: int, cadence: float = 0.0) -> Intent:
    return Intent(
        cadence=np.full(b, cadence),
        turn_rate=np.zeros(b),
        hand_rates=np.zeros((b, 3)),
        gesture_amplitude=np.zeros((b, 3)),
        gesture_frequency=np.full((b, 3), 0.5),
        lean=np.zeros(b),
    )


def _stepping(b: int) -> Intent:
    return _still(b, cadence=1.7)


def test_the_head_takes_what_the_eyes_cannot_of_the_goal_bearing():
    pop = Population(
        "goal_only", "", gaze=True, eye_range_deg=(10.0, 20.0), gaze_onset_s=(0.0, 0.0)
    )
    g, _ = _behaviour(pop, range(6))
    eye = np.deg2rad(g.values["eye_range_deg"])
    assert np.all((eye >= np.deg2rad(10.0)) & (eye <= np.deg2rad(20.0))) and np.ptp(eye) > 0
    bearing = np.deg2rad([5.0, 30.0, -50.0, 100.0, -170.0, 0.0])
    h = np.deg2rad([0.0, 0.0, 10.0, 0.0, 0.0, 0.0])
    gaze = bearing + h  # the goal relative to the torso
    want = np.sign(gaze) * np.minimum(np.maximum(np.abs(gaze) - eye, 0.0), np.deg2rad(70.0))
    heads = []
    for _ in range(30):
        out = g.intent(_still(6), h, bearing, np.full((6, 15), 5.0), np.zeros(6, bool))
        np.testing.assert_allclose(g.head_target, want)
        heads.append(out.head_yaw)
    assert np.all(g.mode == GOAL)
    # the head turns toward its target over several control steps and stops on it
    heads = np.array(heads)
    np.testing.assert_allclose(heads[-1], want)
    assert np.all(np.abs(heads[0]) < np.abs(want) + 1e-12) and np.abs(heads[0] - want).max() > 0.1
    assert np.all(np.diff(np.abs(heads), axis=0) >= -1e-12)  # no overshoot, no reversal


def test_the_head_stays_straight_until_the_user_has_seen_the_scene():
    pop = Population("goal_only", "", gaze=True, eye_range_deg=(0.0, 0.0), gaze_onset_s=(0.2, 0.4))
    g, _ = _behaviour(pop, range(20))
    onset = g.values["gaze_onset_s"]
    for k in range(6):
        out = g.intent(
            _still(20), np.zeros(20), np.full(20, 0.5), np.full((20, 15), 5.0), np.zeros(20, bool)
        )
        seen = k * DT >= onset - 1e-9
        np.testing.assert_array_equal(g.head_target, np.where(seen, 0.5, 0.0))
        assert np.all(out.head_yaw[~seen] == 0.0) and np.all(out.head_yaw[seen] > 0.0)
    assert np.all(g.head_target == 0.5)


def test_glances_look_at_the_nearest_thing_and_end_when_it_is_gone():
    pop = Population(
        "glancers",
        "",
        gaze=True,
        eye_range_deg=(0.0, 0.0),
        glance_rate_hz=(2.0, 2.0),
        glance_s=(5.0, 5.0),
        walking_head_deg=80.0,
        gaze_onset_s=(0.0, 0.0),
        glance_cone_deg=90.0,
    )
    g, offsets = _behaviour(pop, [1])
    rays = np.full((1, 15), 5.0)
    rays[0, 3] = 0.8  # something close, to the right
    seen = []
    for _ in range(40):
        out = g.intent(_stepping(1), np.zeros(1), np.zeros(1), rays, np.zeros(1, bool))
        seen.append(g.mode[0])
    assert GLANCE in seen
    k = seen.index(GLANCE)
    assert out.head_yaw[0] == pytest.approx(offsets[3]) and np.all(np.array(seen[k:]) == GLANCE)
    g.intent(_stepping(1), np.zeros(1), np.zeros(1), np.full((1, 15), 5.0), np.zeros(1, bool))
    assert g.mode[0] == GOAL  # nothing near any more
    # standing still, nothing is on a travel path: no glances
    g2, _ = _behaviour(pop, [1])
    for _ in range(40):
        g2.intent(_still(1), np.zeros(1), np.zeros(1), rays, np.zeros(1, bool))
        assert g2.mode[0] == GOAL


def test_only_what_lies_on_the_travel_path_draws_glances():
    """Things within glance_cone_deg of the torso's direction draw glances; a wall beside the
    path does not, and the cone turns with the torso, not with the head."""
    pop = Population(
        "glancers",
        "",
        gaze=True,
        eye_range_deg=(0.0, 0.0),
        glance_rate_hz=(2.0, 2.0),
        glance_s=(5.0, 5.0),
        gaze_onset_s=(0.0, 0.0),
        glance_cone_deg=30.0,
    )
    g, offsets = _behaviour(pop, [1])
    side = int(np.argmin(np.abs(offsets - np.deg2rad(-70.0))))  # 70 deg to the right
    ahead = int(np.argmin(np.abs(offsets - np.deg2rad(20.0))))  # 20 deg to the left
    assert abs(np.rad2deg(offsets[side]) + 70) < 7 and abs(np.rad2deg(offsets[ahead]) - 20) < 7
    wall = np.full((1, 15), 5.0)
    wall[0, side] = 0.5  # nearer than anything else, but beside the path
    modes = []
    for _ in range(60):
        g.intent(_stepping(1), np.zeros(1), np.zeros(1), wall, np.zeros(1, bool))
        modes.append(g.mode[0])
    assert GLANCE not in modes  # 60 steps at 2 Hz: a glance would have started
    both = wall.copy()
    both[0, ahead] = 1.2  # farther than the wall, on the path
    for _ in range(60):
        g.intent(_stepping(1), np.zeros(1), np.zeros(1), both, np.zeros(1, bool))
        if g.mode[0] == GLANCE:
            break
    assert g.mode[0] == GLANCE and g.head_target[0] == pytest.approx(offsets[ahead])
    # the head turned 60 deg right on the torso: the wall's ray (70 deg right of the view) is
    # now 130 deg off the torso, the ray 20 deg left of the view is 40 deg right of it: neither
    g2, _ = _behaviour(pop, [1])
    turned = np.full(1, np.deg2rad(-60.0))
    modes = []
    for _ in range(60):
        g2.intent(_stepping(1), turned, np.zeros(1), both, np.zeros(1, bool))
        modes.append(g2.mode[0])
    assert GLANCE not in modes


def test_looks_around_come_in_bouts_of_exponential_looks_and_walking_bounds_them():
    """Standing, a bout starts at scan_rate_hz and chains looks (geometric, mean scan_looks),
    each held an exponential time of mean scan_s and shifting the gaze by an exponential size
    of mean scan_amplitude_deg; stepping, a bout is one look, at most walking_head_deg from
    the goal."""
    pop = Population(
        "scanners",
        "",
        gaze=True,
        eye_range_deg=(0.0, 0.0),
        scan_rate_hz=(0.2, 0.2),
        scan_s=(1.0, 1.0),
        scan_looks=(3.0, 3.0),
        scan_amplitude_deg=(20.0, 20.0),
        gaze_onset_s=(0.0, 0.0),
        walking_head_deg=25.0,
    )
    b, steps = 300, 600
    g, _ = _behaviour(pop, range(b))
    modes, targets = [], []
    for _ in range(steps):
        g.intent(_still(b), np.zeros(b), np.zeros(b), np.full((b, 15), 5.0), np.zeros(b, bool))
        modes.append(g.mode.copy())
        targets.append(g.head_target.copy())
    modes, targets = np.array(modes), np.array(targets)
    scanning = modes == SCAN
    # a bout of N / h steps on average (h: a look's end per step, N: looks per bout), then a
    # geometric wait of mean 1 / p steps
    h, p = -np.expm1(-DT / 1.0), -np.expm1(-0.2 * DT)
    assert scanning.mean() == pytest.approx((3 / h) / (3 / h + 1 / p), abs=0.03)
    onset = scanning[1:] & ~scanning[:-1]
    first = np.abs(targets[1:][onset])  # a bout's first look, from the goal (straight ahead)
    assert first.size > 500
    assert np.rad2deg(first.mean()) == pytest.approx(20.0 * (1 - np.exp(-3.5)), rel=0.1)
    assert np.median(first) == pytest.approx(np.log(2) * first.mean(), rel=0.15)  # exponential
    changes = scanning[1:] & scanning[:-1] & (targets[1:] != targets[:-1])
    assert changes.sum() / onset.sum() == pytest.approx(2.0, rel=0.15)  # 3 looks per bout
    # stepping: one look per bout, within +-25 deg of the goal (straight ahead)
    g, _ = _behaviour(pop, range(b))
    walk_modes, walk_targets = [], []
    for _ in range(steps):
        g.intent(_stepping(b), np.zeros(b), np.zeros(b), np.full((b, 15), 5.0), np.zeros(b, bool))
        walk_modes.append(g.mode.copy())
        walk_targets.append(g.head_target.copy())
    walk_scan, walk_targets = np.array(walk_modes) == SCAN, np.array(walk_targets)
    assert np.abs(walk_targets).max() <= np.deg2rad(25.0) + 1e-12
    assert (walk_scan[1:] & walk_scan[:-1] & (walk_targets[1:] != walk_targets[:-1])).sum() == 0
    assert walk_scan.mean() == pytest.approx((1 / h) / (1 / h + 1 / p), abs=0.03)


def test_interacting_users_look_down_at_the_hand():
    pop = replace(POPULATIONS["typical"], scan_rate_hz=(0.0, 0.0), gaze_onset_s=(0.0, 0.0))
    g, _ = _behaviour(pop, range(4))
    inter = np.array([True, False, True, False])
    out = g.intent(_still(4), np.zeros(4), np.deg2rad([60.0] * 4), np.full((4, 15), 5.0), inter)
    down = np.deg2rad(g.values["look_down_deg"])
    np.testing.assert_allclose(out.lean, np.where(inter, down, 0.0))
    assert np.all(down >= np.deg2rad(20.0))
    assert np.all(out.head_yaw[inter] == 0.0) and np.all(out.head_yaw[~inter] > 0.0)
    assert np.all(g.mode[inter] == HAND)


def test_nod_bouts_have_their_cycles_and_share_of_time():
    pop = Population(
        "nod",
        "",
        nod_rate_hz=(0.2, 0.2),
        nod_cycles=(3.0, 3.0),
        nod_frequency_hz=(2.0, 2.0),
        nod_amplitude_deg=(10.0, 10.0),
    )
    b, steps = 100, 600
    g, _ = _behaviour(pop, range(b))
    nodding, amp, freq = [], [], []
    for _ in range(steps):
        out = g.intent(
            _still(b), np.zeros(b), np.zeros(b), np.full((b, 15), 5.0), np.zeros(b, bool)
        )
        nodding.append(g.nodding)
        amp.append(out.gesture_amplitude[:, 1])
        freq.append(out.gesture_frequency[:, 1])
        assert np.all(out.head_yaw == 0.0)  # no gaze: the head stays straight
    nodding = np.array(nodding)
    np.testing.assert_array_equal(np.array(amp), np.where(nodding, np.deg2rad(10.0), 0.0))
    assert np.all(np.array(freq) == 2.0)
    # bouts of 3 cycles / 2 Hz = 1.5 s (15 control steps), then a geometric wait
    p = -np.expm1(-0.2 * DT)
    assert nodding.mean() == pytest.approx(15 / (15 + (1 - p) / p), abs=0.02)


def test_a_batch_of_behaviours_reproduces_single_users_bit_for_bit():
    pop = POPULATIONS["gaze_scanners"]
    seeds, steps = [4, 9, 2], 80
    rng = np.random.default_rng(5)
    bearing = rng.uniform(-3, 3, (steps, 3))
    rays = rng.uniform(0.3, 5.0, (steps, 3, 15))
    h = rng.uniform(-1, 1, (steps, 3))
    inter = rng.uniform(size=(steps, 3)) < 0.2

    def play(rows):
        g, _ = _behaviour(pop, [seeds[i] for i in rows])
        out = []
        for k in range(steps):
            it = g.intent(
                _still(len(rows)), h[k, rows], bearing[k, rows], rays[k, rows], inter[k, rows]
            )
            out.append(np.concatenate([it.head_yaw, it.gesture_amplitude[:, 1], it.lean]))
        return np.array(out).reshape(steps, 3, len(rows))

    batch = play([0, 1, 2])
    for i in range(3):
        np.testing.assert_array_equal(batch[..., i], play([i])[..., 0])


# ------------------------------------------------------------------------------- in the env


def _episode(population, technique="zhang2021", steps=120, seed=3, action=(0.5, 0, 0, 0, 0)):
    env = gym.make(
        "VRLoco-Approach-v0", population=population, technique=technique, max_episode_steps=steps
    )
    obs, _ = env.reset(seed=seed)
    rows = [obs]
    infos = []
    for _ in range(steps):
        obs, _, te, tr, info = env.step(np.asarray(action, np.float32))
        rows.append(obs)
        infos.append(info)
        if te or tr:
            break
    return env, np.array(rows), infos


def test_the_default_observation_is_unchanged_and_gaze_adds_head_on_torso():
    plain, _, _ = _episode(None, steps=2)
    nod, _, _ = _episode("nodders", steps=2)
    assert "head_on_torso" not in plain.unwrapped.observation_spec
    env, obs, _ = _episode("typical", steps=30, action=(-1, 0, 0, 0, 0))
    spec = env.unwrapped.observation_spec
    assert (
        spec.names[: plain.unwrapped.observation_spec.size]
        == plain.unwrapped.observation_spec.names
    )
    assert spec.size == plain.unwrapped.observation_spec.size + 1
    # the field is the true head yaw on the torso at the step's end
    got = spec.decode(obs[-1])["head_on_torso"][0]
    true = env.unwrapped.core.last.motion.head_on_torso_yaw[0, -1]
    assert got == pytest.approx(true, abs=1e-6)
    assert "head_on_torso" in nod.unwrapped.observation_spec  # nodders look at the goal too


def test_the_idealised_population_is_the_default_user_bit_for_bit():
    _, a, _ = _episode(None, steps=40)
    _, b, _ = _episode("idealised", steps=40)
    np.testing.assert_array_equal(a, b)


def test_a_vector_env_with_a_population_matches_single_envs_across_autoresets():
    from vrloco_env.vector import VRLocoVectorEnv

    n, steps, horizon = 2, 30, 12
    act = np.array([[0.5, 0.1, 0.2, 0, 0], [0.8, -0.3, 0, 0, 0]], np.float32)
    envs = VRLocoVectorEnv(
        n, task="approach", population="gaze_scanners", max_episode_steps=horizon
    )
    obs, _ = envs.reset(seed=7)
    vec = [obs]
    for _ in range(steps):
        obs, *_ = envs.step(act)
        vec.append(obs)
    vec = np.array(vec)
    for i in range(n):
        env = gym.make("VRLoco-Approach-v0", population="gaze_scanners", max_episode_steps=horizon)
        obs, _ = env.reset(seed=7 + i)
        single = [obs]
        for _ in range(steps):
            obs, _, te, tr, _ = env.step(act[i])
            if te or tr:
                obs, _ = env.reset()
            single.append(obs)
        np.testing.assert_array_equal(vec[:, i], np.array(single))


@pytest.mark.slow
def test_nodding_while_standing_makes_zhang2021_count_phantom_steps():
    """Nods reach the step detector: a standing user who nods gets steps from Zhang 2021's
    |f| detector (the failure mode of head-IMU step detection the population exposes)."""
    nodder = replace(
        POPULATIONS["nodders"],
        name="always_nods",
        gaze=False,
        nod_rate_hz=(1.0, 1.0),
        nod_amplitude_deg=(15.0, 15.0),
        nod_frequency_hz=(2.0, 2.0),
    )
    counts = {}
    for tech in ("zhang2021", "nod_robust"):
        _, _, infos = _episode(nodder, technique=tech, steps=300, action=(-1, 0, 0, 0, 0))
        assert sum(i["true_steps"] for i in infos) == 0
        counts[tech] = sum(i["detected_steps"] for i in infos)
        _, _, still = _episode(None, technique=tech, steps=300, action=(-1, 0, 0, 0, 0))
        assert sum(i["detected_steps"] for i in still) == 0  # without nods: none
    assert counts["zhang2021"] >= 5
    assert counts["nod_robust"] < counts["zhang2021"]


@pytest.mark.slow
def test_head_directed_steering_walks_where_the_head_looks():
    """A user stepping straight ahead with the body while the head scans: Zhang 2021 moves the
    body along the head's estimated yaw, torso steering (the Kinect's shoulders) along the body.
    Measured on the locomotion's own displacements (before any blocking by the room)."""
    scanner = replace(
        POPULATIONS["gaze_scanners"],
        name="scan_only",
        eye_range_deg=(0.0, 0.0),
        scan_rate_hz=(1.0, 1.0),
        scan_s=(2.0, 2.0),
        glance_rate_hz=(0.0, 0.0),
        scan_amplitude_deg=(60.0, 60.0),
        nod_rate_hz=(0.0, 0.0),
    )
    off = {}
    for tech in ("zhang2021", "torso_steering"):
        env = gym.make(
            "VRLoco-Approach-v0", population=scanner, technique=tech, max_episode_steps=150
        )
        env.reset(seed=3)
        core = env.unwrapped.core
        start_yaw = core.layouts[0].start[2]
        angles, heads = [], []
        for _ in range(150):
            env.step(np.array([0.5, 0, 0, 0, 0], np.float32))
            d = core.last.displacement[0]
            heads.append(core.last.motion.head_on_torso_yaw[0, -1])
            if np.hypot(*d) > 1e-9:
                angles.append(np.angle(np.exp(1j * (np.arctan2(d[1], d[0]) - start_yaw))))
        assert len(angles) > 15 and np.rad2deg(np.ptp(heads)) > 60.0  # eq 17 steps; scans
        off[tech] = np.rad2deg(np.abs(angles))
    assert off["zhang2021"].max() > 30.0 and np.median(off["zhang2021"]) > 5.0
    assert off["torso_steering"].max() < 10.0
