"""The user populations against the evidence they were calibrated on.

* Idle looking (standing, goal ahead, nothing near) has the *shape* of the head turns of people
  freely viewing 360-degree videos, seated or standing (not walking), in the tuning files of
  ``$VRLOCO_DATA/head_traces`` (even video numbers): turn sizes, intervals, the main sequence;
  and stays below their *rate*, an upper bound for a user waiting in a VR room.
* Walking (stepping in place straight ahead, obstacles coming near), head turns beyond the
  38 deg and 185 deg/s of Pozzo et al. (1990) are rare, the head yaws once per stride (Grasso
  et al.) and moves below 4 Hz (Cromwell et al. 2001).
* Stepping in place, the body turns within the Fukuda figures (30 deg in 50 steps, 45 deg in
  100) while the spot drifts forward.

The tuning files' statistics are written here (:data:`TUNING`) so that the tests run without the
data; :func:`test_the_tuning_statistics_are_those_of_the_tuning_files` recomputes them where the
data is present.
"""

from __future__ import annotations

import numpy as np
import pytest

from agents.recordings.head_motion_stats import TURN_SPEED_DEG_S, head_motion_samples
from vrloco_env.batch_rng import BatchRng
from vrloco_env.user import Intent, MotionParams, UserMotion
from vrloco_env.user.behaviour import GazeBehaviour
from vrloco_env.user.population import POPULATIONS

DT = 0.1
OFFSETS = np.linspace(-np.pi / 2, np.pi / 2, 15)
#: Turn amplitude classes (deg) of the main sequence: a turn's peak 10-Hz yaw speed by amplitude.
MAIN_SEQUENCE_BINS = (10.0, 20.0, 30.0, 45.0, 60.0, 90.0)
#: :mod:`agents.recordings.head_motion_stats` at 10 Hz of the tuning files (even video numbers)
#: per dataset:
#: turn amplitude quartiles (deg, turns >= 10 deg), inter-turn interval p10/p25/p50 (s), turns
#: >= 10 deg per minute, nod-like events per minute, and the main sequence (deg/s, median peak
#: speed of the turns in each class of :data:`MAIN_SEQUENCE_BINS`).
TUNING = {
    "corbillon2017": {
        "amplitude": (15.46, 25.20, 46.41),
        "intervals": (0.5, 0.9, 1.6),
        "turns_per_min": 19.66,
        "nods_per_min": 4.35,
        "main_sequence": (51.6, 69.5, 87.1, 102.0, 116.7),
    },
    "lo2017": {
        "amplitude": (17.72, 29.96, 58.98),
        "intervals": (0.6, 1.0, 1.8),
        "turns_per_min": 19.50,
        "nods_per_min": 3.99,
        "main_sequence": (55.0, 77.5, 97.6, 111.3, 138.1),
    },
    "wu2017": {
        "amplitude": (17.30, 30.04, 64.37),
        "intervals": (0.7, 1.1, 1.9),
        "turns_per_min": 15.61,
        "nods_per_min": 3.71,
        "main_sequence": (44.0, 61.3, 75.0, 87.5, 107.0),
    },
}


def _span(key: str) -> tuple[np.ndarray, np.ndarray]:
    """The lowest and highest value of a tuning statistic over the three datasets."""
    values = np.array([np.atleast_1d(TUNING[ds][key]) for ds in TUNING])
    return values.min(axis=0), values.max(axis=0)


def _turns(yaw_deg: np.ndarray, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """Amplitude (deg) and peak |yaw speed| (deg/s) of every turn of one trace sampled at
    ``fs``: runs of one sign above :data:`~agents.recordings.head_motion_stats.TURN_SPEED_DEG_S`, as
    :mod:`agents.recordings.head_motion_stats` defines them."""
    v = np.diff(yaw_deg) * fs
    sign = np.where(v > TURN_SPEED_DEG_S, 1, np.where(v < -TURN_SPEED_DEG_S, -1, 0))
    before, after = np.r_[0, sign[:-1]], np.r_[sign[1:], 0]
    starts = np.flatnonzero((sign != 0) & (sign != before))
    ends = np.flatnonzero((sign != 0) & (sign != after))
    peak = [np.abs(v[a : b + 1]).max() for a, b in zip(starts, ends, strict=True)]
    return np.abs(yaw_deg[ends + 1] - yaw_deg[starts]), np.array(peak).reshape(-1)


def _main_sequence(yaw_deg: list[np.ndarray], fs: float = 10.0) -> np.ndarray:
    """Median peak |yaw speed| (deg/s) of the turns in each amplitude class of
    :data:`MAIN_SEQUENCE_BINS`, over the traces ``yaw_deg`` (deg)."""
    amp, peak = (np.concatenate(x) for x in zip(*(_turns(y, fs) for y in yaw_deg), strict=True))
    lo, hi = MAIN_SEQUENCE_BINS[:-1], MAIN_SEQUENCE_BINS[1:]
    return np.array([np.median(peak[(amp >= a) & (amp < b)]) for a, b in zip(lo, hi, strict=True)])


def _intent(b: int, cadence: np.ndarray | float = 0.0) -> Intent:
    return Intent(
        cadence=np.broadcast_to(cadence, (b,)).copy(),
        turn_rate=np.zeros(b),
        hand_rates=np.zeros((b, 3)),
        gesture_amplitude=np.zeros((b, 3)),
        gesture_frequency=np.full((b, 3), 0.5),
        lean=np.zeros(b),
    )


def _simulate(
    population, users: int, seconds: float, seed: int, cadence=0.0, obstacles: bool = False
):
    """Users of ``population`` looking at a goal straight ahead (the action asks for no turn),
    standing (``cadence`` 0) or stepping in place; with ``obstacles``, something lies on the
    travel path 1 m ahead, 13 deg right, 3 s in every 8 s.

    Returns:
        The motion chunks (one per control step) and the behaviour.
    """
    b = users
    motion = UserMotion(MotionParams(), BatchRng.from_seeds(range(seed + 10**6, seed + 10**6 + b)))
    motion.reset()
    g = GazeBehaviour(population, BatchRng.from_seeds(range(seed, seed + b)), DT, OFFSETS)
    motion.scale_style(np.arange(b), g.reset())
    head = np.zeros(b)
    chunks = []
    for k in range(round(seconds / DT)):
        rays = np.full((b, OFFSETS.size), 5.0)
        if obstacles:
            rays[((k + np.arange(b)) % 80) < 30, 6] = 1.0
        intent = g.intent(_intent(b, cadence), head, -head, rays, np.zeros(b, bool))
        chunks.append(motion.advance(intent))  # validated: head and turn within their ranges
        head = chunks[-1].head_on_torso_yaw[:, -1]
    return chunks, g


def _standing_samples(name: str, users: int = 300, seed: int = 1000):
    chunks, _ = _simulate(POPULATIONS[name], users, 60.0, seed)
    ypr = np.stack([c.ypr[:, -1, :2] for c in chunks], axis=1)  # 10 Hz, the world frame
    return head_motion_samples(list(ypr[..., 0]), list(ypr[..., 1]), rate_hz=10.0), ypr


@pytest.fixture(scope="module")
def typical_standing():
    return _standing_samples("typical")


def test_the_tuning_statistics_are_those_of_the_tuning_files(real_data):
    """:data:`TUNING`, the reference of the tests below, is what the tuning files give (skipped
    where the head traces are absent)."""
    from agents.experiments.head_behaviour import is_held_out, real_samples
    from agents.recordings.head_motion_stats import prepare_traces
    from agents.recordings.head_traces import dataset_files, read_head_traces

    for ds, paths in dataset_files(real_data("head_traces")).items():
        tuning = [p for p in paths if not is_held_out(p)]
        assert tuning and all(int(p.stem) % 2 == 0 for p in tuning)
        samples, _ = real_samples(tuning)
        s = samples.stats()
        want = TUNING[ds]
        np.testing.assert_allclose(s.turn_amplitude_p25_p50_p75, want["amplitude"], atol=0.01)
        np.testing.assert_allclose(s.interval_p10_p25_p50_p75_p90[:3], want["intervals"])
        assert s.turns_per_min[0] == pytest.approx(want["turns_per_min"], abs=0.01)
        assert s.nods_per_min == pytest.approx(want["nods_per_min"], abs=0.01)
        yaw = []
        for path in tuning:
            for t, pitch, y in read_head_traces(path).viewings():
                try:
                    traces, _ = prepare_traces(y, pitch, times=t, resample_hz=10.0)
                except ValueError:
                    continue
                yaw.append(np.rad2deg(traces[0][0]))
        np.testing.assert_allclose(_main_sequence(yaw), want["main_sequence"], atol=0.06)


def test_idle_looking_has_the_shape_of_the_tuning_traces_turns(typical_standing):
    """Turn sizes within 3 deg, intervals within 0.15 s and the main sequence within 10 % of the
    span of the three tuning datasets."""
    samples, ypr = typical_standing
    s = samples.stats()
    lo, hi = _span("amplitude")
    assert np.all(
        (np.array(s.turn_amplitude_p25_p50_p75) >= lo - 3.0)
        & (np.array(s.turn_amplitude_p25_p50_p75) <= hi + 3.0)
    ), s
    lo, hi = _span("intervals")
    got = np.array(s.interval_p10_p25_p50_p75_p90[:3])
    assert np.all((got >= lo - 0.15) & (got <= hi + 0.15)), got
    lo, hi = _span("main_sequence")
    got = _main_sequence(list(np.rad2deg(ypr[..., 0])))
    assert np.all((got >= 0.9 * lo) & (got <= 1.1 * hi)), got


@pytest.mark.parametrize("name", ["typical", "gaze_scanners", "nodders"])
def test_idle_looking_stays_below_the_free_viewing_rate(name, typical_standing):
    """Free viewing of 360-degree video bounds idle looking from above: fewer head turns of at
    least 10 deg per minute than the least of the tuning datasets; the nod-like events too,
    except for ``nodders``, whose frequent nods are the point of that population."""
    samples = typical_standing[0] if name == "typical" else _standing_samples(name)[0]
    s = samples.stats()
    assert 2.0 < s.turns_per_min[0] < _span("turns_per_min")[0][0]
    if name == "nodders":
        assert s.nods_per_min > 2 * _span("nods_per_min")[1][0]
    else:
        assert s.nods_per_min < _span("nods_per_min")[0][0]


@pytest.mark.parametrize("name", ["typical", "gaze_scanners", "nodders"])
def test_walking_head_turns_beyond_the_walking_bounds_are_rare(name):
    """Stepping in place straight ahead at 117 steps/min, with something coming near on the
    path: head turns (in the world, at the IMU's 100 Hz) larger than 38 deg occur at most
    0.3 per minute and in at most 5 % of the turns of 10 deg or more (measured: ``typical``
    0.02 per minute, ``gaze_scanners`` 0.18); none is faster than 185 deg/s (Pozzo et al.
    1990; measured peaks below 120 deg/s)."""
    chunks, _ = _simulate(POPULATIONS[name], 100, 60.0, 2000, cadence=1.95, obstacles=True)
    yaw = np.rad2deg(np.concatenate([c.ypr[:, :, 0] for c in chunks], axis=1))
    amp, peak = (np.concatenate(x) for x in zip(*(_turns(y, 100.0) for y in yaw), strict=True))
    minutes = yaw.shape[0] * 1.0
    big = amp >= 10.0
    assert big.sum() / minutes > 0.5  # the heads do turn while walking
    assert (amp > 38.0).sum() / minutes <= 0.3
    assert (amp > 38.0).sum() <= 0.05 * big.sum()
    assert peak.max() < 185.0


def test_the_walking_head_yaws_once_per_stride_and_below_4_hz():
    """The head's yaw rate in space, stepping at 1.95 steps/s: its spectrum peaks at the stride
    frequency, 0.975 Hz (Grasso et al.), and holds less than 1 % of its power above 4 Hz
    (Cromwell et al. 2001)."""
    chunks, _ = _simulate(POPULATIONS["typical"], 50, 60.0, 3000, cadence=1.95, obstacles=True)
    yaw = np.unwrap(np.concatenate([c.ypr[:, :, 0] for c in chunks], axis=1), axis=1)
    rate = np.diff(yaw, axis=1) * 100.0
    freq = np.fft.rfftfreq(rate.shape[1], 0.01)
    power = (np.abs(np.fft.rfft(rate - rate.mean(axis=1, keepdims=True), axis=1)) ** 2).sum(0)
    assert freq[1 + np.argmax(power[1:])] == pytest.approx(1.95 / 2, abs=0.02)
    assert power[freq > 4.0].sum() < 0.01 * power.sum()


def test_stepping_in_place_turns_within_the_fukuda_figures():
    """Stepping in place at 117 +- 9 steps/min with no turn asked, each user's body turns by its
    drawn degrees per step: after 50 steps by less than 30 deg, after 100 by less than 45
    (Fukuda's cut-offs for healthy adults), left and right, the most drifting users near the
    bound; the turn is in the true motion (the body's yaw the IMU and Kinect follow)."""
    b = 200
    cadence = np.random.default_rng(1).normal(1.95, 0.15, b).clip(1.2, 2.2)
    chunks, g = _simulate(POPULATIONS["typical"], b, 70.0, 4000, cadence=cadence)
    body = np.concatenate([c.body_yaw for c in chunks], axis=1)
    steps = np.cumsum(np.concatenate([c.step for c in chunks], axis=1), axis=1)
    rate = g.values["wip_turn_deg_per_step"]
    for n, bound in ((50, 30.0), (100, 45.0)):
        at = np.argmax(steps >= n, axis=1)
        assert np.all(steps[np.arange(b), at] == n)  # every user took n steps
        turned = np.rad2deg(body[np.arange(b), at] - body[:, 0])
        assert np.all(np.abs(turned) < bound)
        np.testing.assert_allclose(turned, rate * n, atol=0.5)  # rate * (n +- half a step)
    assert (rate > 0).sum() > 60 and (rate < 0).sum() > 60
    assert np.abs(rate).max() * 100 > 40.0
    # the head turns with the body, and the gyro senses it: the integrated true body-frame
    # rate about z follows the head's yaw in the world
    head = np.concatenate([c.ypr[:, :, 0] for c in chunks], axis=1)
    gyro = np.concatenate([c.omega[:, :, 2] for c in chunks], axis=1)
    turned = np.rad2deg(head[:, -1] - head[:, 0])
    sensed = np.rad2deg(gyro[:, 1:].sum(axis=1) * 0.01)
    np.testing.assert_allclose(sensed, turned, atol=1.0 + 0.02 * np.abs(turned).max())
