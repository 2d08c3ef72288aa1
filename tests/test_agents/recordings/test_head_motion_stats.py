"""Head-motion statistics on synthetic traces whose answers are known, and their input checks."""

import numpy as np
import pytest

from agents.recordings.head_motion_stats import (
    STATS_KEYS,
    head_motion_samples,
    head_motion_stats,
)

FS = 10.0


def steps_trace(
    step_deg=40.0,
    period_s=4.0,
    first_s=1.0,
    duration_s=60.0,
    ramp_s=0.4,
    rate_hz=FS,
    offset_deg=0.0,
):
    """Yaw stepping ``step_deg`` every ``period_s`` from ``first_s``, each step a ramp at a
    constant speed ``step_deg / ramp_s``; pitch level. Returns (times, yaw rad, pitch rad)."""
    t = np.arange(round(duration_s * rate_hz) + 1) / rate_hz
    starts = np.arange(first_s, duration_s - ramp_s, period_s)
    yaw = np.zeros_like(t)
    for s in starts:  # a loop over the 15 steps that build the truth, not over samples
        yaw += step_deg * np.clip((t - s) / ramp_s, 0.0, 1.0)
    return t, np.deg2rad(yaw + offset_deg), np.zeros_like(t)


def test_steps_every_4_s_give_15_turns_a_minute_and_4_s_intervals():
    t, yaw, pitch = steps_trace()
    s = head_motion_stats(yaw, pitch, times=t)
    assert s.turns_per_min == pytest.approx((15.0, 15.0, 15.0, 0.0))
    assert s.turn_amplitude_p25_p50_p75 == pytest.approx((40.0, 40.0, 40.0))
    assert s.interval_p10_p25_p50_p75_p90 == pytest.approx((4.0,) * 5)
    assert s.interval_cv == pytest.approx(0.0, abs=1e-12)
    # 60 of the 600 sample pairs turn at 100 deg/s, the rest are still
    assert s.yaw_speed_p50_p75_p90_p95_p99[:2] == (0.0, 0.0)
    assert s.yaw_speed_p50_p75_p90_p95_p99[3:] == pytest.approx((100.0, 100.0))
    assert s.still_fraction == pytest.approx(540 / 600)
    assert s.pitch_range_5_95_deg == 0.0 and s.nods_per_min == 0.0


def test_turns_below_20_deg_per_s_are_no_turns_and_reversals_split_turns():
    # 40 deg in 2.5 s is 16 deg/s: under the turn speed
    t, yaw, pitch = steps_trace(ramp_s=2.5)
    s = head_motion_stats(yaw, pitch, times=t)
    assert s.turns_per_min == (0.0, 0.0, 0.0, 0.0) and s.turn_amplitude_p25_p50_p75 is None
    assert s.interval_p10_p25_p50_p75_p90 is None and s.interval_cv is None
    # a 30 deg swing to the left and straight back: two turns of 30 deg, 0.3 s apart
    t = np.arange(201) / FS
    yaw = np.deg2rad(np.interp(t, [5.0, 5.3, 5.6], [0.0, 30.0, 0.0]))
    s = head_motion_samples(yaw, np.zeros_like(t), rate_hz=FS)
    np.testing.assert_allclose(s.turn_amplitude, [30.0, 30.0])
    np.testing.assert_allclose(s.intervals, [0.3])


def test_pooling_concatenates_events_instead_of_averaging():
    """One trace with turns every 2 s (60 s) and one with none (60 s): 15 turns a minute over
    both; the intervals are the first trace's alone (never across traces)."""
    t, yaw, pitch = steps_trace(period_s=2.0)
    still = np.zeros_like(t)
    s = head_motion_stats([yaw, still], [pitch, still], times=[t, t])
    assert s.turns_per_min[0] == pytest.approx(15.0)
    assert s.interval_p10_p25_p50_p75_p90 == pytest.approx((2.0,) * 5)
    b = head_motion_stats(np.stack([yaw, still]), np.stack([pitch, still]), rate_hz=FS)
    assert b == s


def test_a_still_head_is_still_all_the_time():
    t = np.arange(301) / FS
    s = head_motion_stats(np.full_like(t, 0.7), np.full_like(t, -0.2), times=t)
    assert s.still_fraction == 1.0
    assert s.yaw_speed_p50_p75_p90_p95_p99 == (0.0,) * 5
    assert s.turns_per_min == (0.0,) * 4 and s.nods_per_min == 0.0
    assert s.pitch_range_5_95_deg == 0.0
    assert list(s.to_json()) == list(STATS_KEYS)
    assert s.to_json()["turn_amplitude_p25_p50_p75"] is None


def test_the_pitch_range_of_a_sinusoid_is_its_arcsine_quantiles():
    """pitch = A sin(2 pi f t) at phases spread evenly over the circle: the q-quantile is
    A sin(pi (q - 0.5)), so the 5-95 % range is 2 A sin(0.45 pi) = 1.9754 A. (f = 0.1 sqrt 2 Hz,
    incommensurate with the 10 Hz samples, spreads the phases evenly.)"""
    amplitude = 20.0
    t = np.arange(6001) / FS  # 600 s
    pitch = np.deg2rad(amplitude * np.sin(2 * np.pi * 0.1 * np.sqrt(2.0) * t))
    s = head_motion_stats(np.zeros_like(t), pitch, times=t)
    assert s.pitch_range_5_95_deg == pytest.approx(2 * amplitude * np.sin(0.45 * np.pi), rel=1e-4)
    assert s.nods_per_min == 0.0  # no nod: 2 deg of change within 0.5 s of a peak


def nod_trace(rate_hz=FS):
    """60 s of pitch: 8 dips of 8 deg over 0.6 s, 4 rises of 8 deg over 0.6 s, a bout of 3 nod
    cycles of +-8 deg at 2 Hz (3 down and 3 up excursions: 6 events); and what is no nod: a dip
    of 4 deg, a dip of 10 deg over 4 s, a held 10 deg change. 18 events in all."""
    t = np.arange(round(60 * rate_hz) + 1) / rate_hz
    p = np.zeros_like(t)

    def bump(centre, depth, width):
        x = np.clip((t - centre) / width, -0.5, 0.5)
        return depth * 0.5 * (1 + np.cos(2 * np.pi * x))

    for c in (2, 5, 8, 11, 14, 17, 20, 23):
        p -= bump(c, 8.0, 0.6)
    for c in (26, 29, 32, 35):
        p += bump(c, 8.0, 0.6)
    bout = (t >= 40.0) & (t <= 41.5)
    p[bout] += 8.0 * np.sin(2 * np.pi * 2.0 * (t[bout] - 40.0))
    p -= bump(45, 4.0, 0.6) + bump(50, 10.0, 4.0)
    p += np.where(t > 55, 10.0, 0.0)
    return t, np.zeros_like(t), np.deg2rad(p)


def test_nod_like_events_are_counted_exactly():
    t, yaw, pitch = nod_trace()
    s = head_motion_samples(yaw, pitch, times=t)
    assert s.nods.tolist() == [18]
    assert s.stats().nods_per_min == pytest.approx(18.0)
    # the same head sampled at 50 Hz and resampled to 10 Hz
    t50, yaw50, pitch50 = nod_trace(50.0)
    assert head_motion_samples(yaw50, pitch50, times=t50).nods.tolist() == [18]


def test_wrapped_yaw_gives_what_the_unwrapped_yaw_gives():
    t, yaw, pitch = steps_trace(offset_deg=170.0, period_s=2.0)  # crosses +-180 deg many times
    wrapped = (yaw + np.pi) % (2 * np.pi) - np.pi
    assert np.abs(np.diff(wrapped)).max() > np.pi  # the wraps are there
    a = head_motion_samples(yaw, pitch, times=t)
    b = head_motion_samples(wrapped, pitch, times=t)
    # yaw turns from 170 to 1370 deg: it crosses 180, 540, 900 and 1260 deg
    assert a.yaw_unwraps.tolist() == [0] and b.yaw_unwraps.tolist() == [4]
    sa, sb = a.stats().to_json(), b.stats().to_json()
    for key in STATS_KEYS:
        assert np.allclose(sa[key], sb[key], atol=1e-9), key


def test_irregular_times_and_other_rates_resample_to_10_hz():
    t, yaw, pitch = steps_trace(rate_hz=50.0)
    jitter = np.random.default_rng(1).uniform(-0.004, 0.004, t.size)
    jitter[[0, -1]] = 0.0
    s = head_motion_stats(
        np.interp(t + jitter, t, yaw), np.interp(t + jitter, t, pitch), times=t + jitter
    )
    assert s.turns_per_min == pytest.approx((15.0, 15.0, 15.0, 0.0))
    assert s.interval_p10_p25_p50_p75_p90 == pytest.approx((4.0,) * 5, abs=1e-9)
    assert head_motion_samples(yaw, pitch, rate_hz=50.0).yaw_speed.size == 600


@pytest.mark.parametrize(
    ("change", "match"),
    [
        (
            lambda t, y, p: (t, np.where(np.arange(t.size) == 7, np.nan, y), p),
            r"yaw: sample 7 is nan: every sample must be finite",
        ),
        (
            lambda t, y, p: (t, y, np.where(np.arange(t.size) == 9, np.inf, p)),
            r"pitch: sample 9 is inf",
        ),
        (
            lambda t, y, p: (
                np.delete(t, np.s_[100:110]),
                np.delete(y, np.s_[100:110]),
                np.delete(p, np.s_[100:110]),
            ),
            r"times: a gap of 1.1 s after sample 99 .* more than 1.5 x the median step",
        ),
        (lambda t, y, p: (t * 2.5, y, p), r"times: a sampling rate of 4 Hz .* at least 5 Hz"),
        (lambda t, y, p: (t[:95], y[:95], p[:95]), r"yaw: 9.4 s long: .* at least 10 s"),
        (
            lambda t, y, p: (t, y, np.where(t > 20, np.deg2rad(95.0), p)),
            r"pitch: sample 201 is 95.0 deg: pitch must lie in \[-90, 90\] deg",
        ),
        (
            lambda t, y, p: (
                np.arange(2001) / 100.0,
                np.zeros(2001),  # 80 deg in 0.01 s
                np.where(np.arange(2001) > 500, np.deg2rad(80.0), 0.0),
            ),
            r"pitch: a jump of 80.0 deg between samples 500 and 501 \(8000 deg/s\): .* faster "
            r"than 1000 deg/s",
        ),
        (lambda t, y, p: (t[::-1], y, p), r"times: sample 1 .* times must increase strictly"),
        (lambda t, y, p: (t, y, p[:-1]), r"yaw, pitch, times: 601, 600 and 601 samples"),
    ],
)
def test_bad_input_is_one_clear_error(change, match):
    t, y, p = steps_trace()
    t, y, p = change(t, y, p)
    with pytest.raises(ValueError, match=match):
        head_motion_stats(y, p, times=t)


def test_bad_arguments_name_the_argument_and_the_trace():
    t, y, p = steps_trace()
    with pytest.raises(ValueError, match=r"yaw\[1\]: sample 3 is nan"):
        head_motion_stats([y, np.where(t == t[3], np.nan, y)], [p, p], times=[t, t])
    with pytest.raises(ValueError, match=r"rate_hz=4: must be in \[5, inf\) Hz"):
        head_motion_stats(y, p, rate_hz=4)
    with pytest.raises(ValueError, match=r"resample_hz=2: must be in \[5, inf\) Hz"):
        head_motion_stats(y, p, times=t, resample_hz=2)
    with pytest.raises(ValueError, match="one of them"):
        head_motion_stats(y, p, times=t, rate_hz=10.0)
    with pytest.raises(ValueError, match="one of them"):
        head_motion_stats(y, p)
    with pytest.raises(ValueError, match=r"pitch: 1 traces, yaw has 2"):
        head_motion_stats([y, y], [p], rate_hz=FS)
    with pytest.raises(ValueError, match=r"yaw: no traces"):
        head_motion_stats([], [], rate_hz=FS)
    with pytest.raises(ValueError, match=r"yaw: must be numbers"):
        head_motion_stats("north", p, rate_hz=FS)
    with pytest.raises(ValueError, match=r"times: 1 arrays for 2 traces"):
        head_motion_stats([y, y], [p, p], times=[t])
