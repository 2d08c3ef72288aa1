"""Step detectors outside the simulator's design envelope, and on the real neck-pouch walk.

Every detector of :data:`estimators.stages.STEPS` and both IMU presets of
:mod:`agents.experiments.head_motions`, on motions the simulated users of the benchmark never
make. Each case reports, pooled over its users and seeds, the true positives, false positives
and misses against the true heel strikes (one-to-one within +-0.2 s,
:func:`agents.benchmark.step_matching.match_step_times`), F1 where the case has steps, and false
steps per minute (false positives over the case's user-minutes: of standing for the standing cases,
in excess of the true steps for the stepping ones). The attitude each detector reads is the
error-state EKF's estimate from the same IMU samples.

Cases (:data:`CASES`; 2 s still, the motion, 2 s still, as the head-motion scripts do):

* **Light steps** — stepping in place at 1.5 steps/s with the heel-strike peak of vertical head
  acceleration (``MotionParams.peak_accel_g``) cut to 0.10 g and 0.06 g, against the model's
  0.12-0.45 g: about 1.2 and 0.7 cm of vertical head travel per step, against the model's 2-3 cm.
  Lee, Ahn & Hwang (Sensors 18(9) 2832, 2018, Fig. 4) show that a "march-in-place" moves a
  headset much less than a "jog-in-place", but give no acceleration; the two values are an
  engineering choice bracketing the detectors' 0.07 g threshold (Zhang 2021's gamma), so they show
  where each detector's floor lies.
* **Heavy nods** — +-35 deg at 1.5 Hz, standing and while stepping at 1.7 steps/s, and fast
  small nods, +-5 deg at 3 Hz, standing. Frequencies: Hale et al. (J. Nonverbal Behav. 44, 2020,
  motion capture of 31 conversing dyads) find head motion of conversation at 0.2-1.1 Hz and fast
  nodding at 2.6-6.5 Hz; 3 Hz is the motion model's limit. Amplitudes: engineering choice (a
  vigorous, emphatic nod; a small listener's nod).
* **Squats** — a slow knee bend, the head going down ``depth`` and back up at ``rate`` Hz, four
  times: 0.3 m at 0.3 Hz and 0.5 m at 0.5 Hz (a body-weight squat of an adult, the head dropping
  with the hips; depth and tempo are an engineering choice). Lee, Ahn & Hwang (2018) name the
  squat as the motion most prone to false steps of an IMU walking-in-place detector. The
  motion model has no squat, so the vertical displacement ``z = -depth (1 - cos 2 pi rate t) / 2``
  and its exact second derivative are added to a standing record's ``pos`` and ``acc``
  (:func:`add_squats`); the head's attitude is left as it is (no trunk lean).
* **Looking down at the hand** — the head pitched down 35 deg, held, then 45 deg with a +-5 deg
  pitch and +-10 deg yaw oscillation following the hand (so 30-50 deg), back to 30 deg, up to
  level and down again, the right hand turning meanwhile; standing and while stepping at 1.7
  steps/s. Lee, Kang & Shin (Ergonomics 58(2), 2015) measured a head flexion of 33-45 deg (50th
  percentile) in 18 people using a smartphone sitting and standing; Lee & Shin (HFES 2015) found
  users spent most of their phone time with the head flexed 30-50 deg. The motion model's
  ``Intent.lean`` is limited to 45 deg; the oscillation reaches 50.
* **Head scanning while walking** — stepping at 1.7 steps/s while looking around: an
  oscillation of yaw +-60 deg at 0.5 Hz and pitch +-20 deg at 0.4 Hz, and gaze shifts (the head
  turning on the torso to a new yaw target, drawn uniformly in +-70 deg, every 1.2 s, with the
  model's main-sequence lag, ``MotionParams.head_turn_lag_s``). 70 deg is inside the active
  range of cervical rotation (70-80 deg, Ferrario et al., J. Orthop. Res. 20(1), 2002); the rates
  are an engineering choice, faster than the head-motion experiment's scan (+-30 deg at 0.3 Hz).

Seeds: the held-out seeds 1000-1002 by default (``--seed S``: S, S+1, S+2), none of which chose
anything; ``--dev`` runs the development seeds 0-2 on which ``nod_robust``'s lever arm was
checked. The output labels which.

The Oxford neck-pouch walk (:func:`oxford_table`): every detector on the real recording against its
foot switches, except those that read a tracked headset's position (``lee2018``), which a
neck-pouch IMU does not give; in the simulated cases they read the head's position with the
tracking noise of :attr:`vrloco_env.config.SensorConfig.headset_position_noise_m`. The recording
has no gyroscope, so the attitude the detectors read is the tilt of the 1 s running mean of the
specific force (:func:`tilt_quaternions`, yaw 0) and the angular rate is zero: ``nod_robust`` runs
as a world-vertical detector without its rotation veto. The ``neck_pouch`` preset
(:meth:`estimators.steps.zhang2021.GaitParams.neck_pouch`) was tuned on this recording, so its
figure is in-sample. :func:`two_fold_gamma` gives the held-out figure: the preset's free parameter
(gamma) is chosen on one half of the recording from a small grid and scored on the other half, both
ways. It holds out the choice of gamma only: the grid, and the detector's other parameters, were
set by people who had seen the whole walk.

Run: ``vrloco experiment step-envelope [--json F] [--seed S] [--dev]``.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from agents.benchmark.step_matching import match_step_times
from agents.experiments.head_motions import PRESETS, Trial, sense_record
from agents.recordings.data import DataMissing, data_path
from estimators.io.oxford import load_oxford
from estimators.rotations import GRAVITY, quat_from_rotvec
from estimators.stages import STEPS
from estimators.steps import GaitParams, bin_average, detect_steps
from vrloco_env.batch_rng import BatchRng
from vrloco_env.config import SensorConfig
from vrloco_env.user import Intent, MotionParams, MotionRecord, UserMotion

__all__ = [
    "CASES",
    "DEV_SEEDS",
    "GAMMA_GRID_G",
    "HELD_OUT_SEEDS",
    "Case",
    "Counts",
    "add_squats",
    "build_trial",
    "count_steps",
    "detected_times",
    "oxford_halves",
    "oxford_table",
    "run_step_envelope",
    "seed_label",
    "tilt_quaternions",
    "two_fold_gamma",
]

FS = 100.0
CONTROL_HZ = 10.0
TOLERANCE_S = 0.2
DEV_SEEDS = (0, 1, 2)
HELD_OUT_SEEDS = (1000, 1001, 1002)
#: gamma values (g) searched by :func:`two_fold_gamma`; the preset's is 0.15 g.
GAMMA_GRID_G = (0.07, 0.09, 0.11, 0.13, 0.15, 0.17, 0.19, 0.21)


@dataclass(frozen=True)
class Case:
    """One scenario: ``plan(users, gen) -> (intents, squats)`` where ``intents`` is one
    :class:`vrloco_env.user.Intent` per control step (``gen`` draws anything random in it) and
    ``squats`` ``(depth m, rate Hz, start s, cycles)`` for :func:`add_squats`, or None;
    ``stepping`` says whether the user steps (else every detection is a false step);
    ``peak_g`` overrides the heel-strike peak (g) at every cadence."""

    name: str
    stepping: bool
    plan: Callable[[int, np.random.Generator], tuple[list[Intent], tuple | None]]
    peak_g: float | None = None


@dataclass
class Counts:
    """Pooled matching of detected vs true heel strikes."""

    tp: int = 0
    fp: int = 0
    misses: int = 0
    true_steps: int = 0
    minutes: float = 0.0

    def add(self, true: NDArray[np.float64], det: NDArray[np.float64], minutes: float) -> None:
        tp, fp, fn = match_step_times(true, det, TOLERANCE_S)
        self.tp += tp
        self.fp += fp
        self.misses += fn
        self.true_steps += int(true.size)
        self.minutes += minutes

    @property
    def f1(self) -> float | None:
        """2 TP / (2 TP + FP + misses); None without true steps (precision and recall of a
        case with nothing to find are not defined: its figure is the false-step rate)."""
        if self.true_steps == 0:
            return None
        return 2 * self.tp / (2 * self.tp + self.fp + self.misses)

    @property
    def fp_per_min(self) -> float:
        return self.fp / self.minutes if self.minutes else 0.0

    def as_dict(self) -> dict:
        f1 = self.f1
        return {
            "tp": self.tp,
            "fp": self.fp,
            "misses": self.misses,
            "true_steps": self.true_steps,
            "f1": None if f1 is None else round(f1, 4),
            "false_steps_per_min": round(self.fp_per_min, 2),
            "user_minutes": round(self.minutes, 3),
        }


def _seg(seconds: float, **kw) -> list[Intent]:
    return [Intent(**kw)] * round(seconds * CONTROL_HZ)


def _deg(x: float) -> float:
    return float(np.deg2rad(x))


def _gesture(amp_deg, freq_hz, cadence: float, seconds: float = 16.0):
    """2 s still, ``seconds`` of the oscillation (at ``cadence``), 2 s still."""
    amp = tuple(_deg(a) for a in amp_deg)

    def plan(users: int, gen: np.random.Generator):
        f = tuple(freq_hz)
        return (
            _seg(2.0, gesture_frequency=f)
            + _seg(seconds, cadence=cadence, gesture_amplitude=amp, gesture_frequency=f)
            + _seg(2.0, gesture_frequency=f)
        ), None

    return plan


def _stepping(cadence: float, seconds: float = 16.0):
    def plan(users: int, gen: np.random.Generator):
        return _seg(2.0) + _seg(seconds, cadence=cadence) + _seg(2.0), None

    return plan


def _squats(depth: float, rate: float, cycles: int = 4):
    def plan(users: int, gen: np.random.Generator):
        seconds = cycles / rate
        return _seg(2.0) + _seg(seconds) + _seg(2.0), (depth, rate, 2.0, cycles)

    return plan


def _look_at_hand(cadence: float):
    """Look down at the hand: 35 deg held, 45 +-5 deg following the hand, 30 deg, level, 40."""

    def plan(users: int, gen: np.random.Generator):
        hand = (0.6, 0.4, 0.0)  # rad/s: the hand turning while the user watches it
        follow = dict(
            gesture_amplitude=(_deg(10.0), _deg(5.0), 0.0), gesture_frequency=(0.2, 0.3, 0.5)
        )
        c = cadence
        return (
            _seg(2.0)
            + _seg(4.0, cadence=c, lean=_deg(35.0), hand_rates=hand)
            + _seg(5.0, cadence=c, lean=_deg(45.0), hand_rates=tuple(-h for h in hand), **follow)
            + _seg(3.0, cadence=c, lean=_deg(30.0), hand_rates=hand)
            + _seg(2.0, cadence=c)
            + _seg(3.0, cadence=c, lean=_deg(40.0), hand_rates=tuple(-h for h in hand))
            + _seg(2.0)
        ), None

    return plan


def _gaze_shifts(cadence: float, seconds: float = 16.0, hold: float = 1.2):
    """Stepping while the head jumps to a new yaw target in +-70 deg every ``hold`` s."""

    def plan(users: int, gen: np.random.Generator):
        out = _seg(2.0)
        for _ in range(round(seconds / hold)):
            target = gen.uniform(-_deg(70.0), _deg(70.0), size=users)
            out += [Intent(cadence=cadence, head_yaw=target)] * round(hold * CONTROL_HZ)
        return out + _seg(2.0), None

    return plan


#: The scenarios, in report order.
CASES: tuple[Case, ...] = (
    Case("light steps 0.10 g, 1.5/s", True, _stepping(1.5), peak_g=0.10),
    Case("light steps 0.06 g, 1.5/s", True, _stepping(1.5), peak_g=0.06),
    Case("nod 35deg 1.5Hz, standing", False, _gesture((0, 35, 0), (1.5, 1.5, 1.5), 0.0)),
    Case("nod 35deg 1.5Hz, 1.7/s", True, _gesture((0, 35, 0), (1.5, 1.5, 1.5), 1.7)),
    Case("nod 5deg 3Hz, standing", False, _gesture((0, 5, 0), (3.0, 3.0, 3.0), 0.0)),
    Case("squat 0.3 m 0.3 Hz", False, _squats(0.3, 0.3)),
    Case("squat 0.5 m 0.5 Hz", False, _squats(0.5, 0.5)),
    Case("look at hand, standing", False, _look_at_hand(0.0)),
    Case("look at hand, 1.7/s", True, _look_at_hand(1.7)),
    Case("scan 60deg 0.5Hz, 1.7/s", True, _gesture((60, 20, 0), (0.5, 0.4, 0.5), 1.7)),
    Case("gaze shifts 70deg, 1.7/s", True, _gaze_shifts(1.7)),
)


def add_squats(record: MotionRecord, depth: float, rate: float, start: float, cycles: int) -> None:
    """Add ``cycles`` squats to ``record`` in place: from ``start`` s the head's vertical
    position gains ``z = -depth (1 - cos(2 pi rate tau)) / 2`` (tau = t - start) and its
    acceleration ``z'' = -depth (2 pi rate)^2 cos(2 pi rate tau) / 2``, for every user.

    ``z`` and ``z'`` are continuous (0 at both ends); ``z''`` steps by ``depth (2 pi rate)^2 / 2``
    at the first and last sample, downward, so the specific force falls there rather than
    rising like a heel strike.
    """
    if not (0.0 < depth <= 1.0 and 0.0 < rate <= 2.0 and cycles >= 1):
        raise ValueError(
            f"squats: depth={depth!r} must be in (0, 1] m, rate={rate!r} in "
            f"(0, 2] Hz, cycles={cycles!r} >= 1"
        )
    tau = record.t - start
    inside = (tau >= 0.0) & (tau <= cycles / rate)
    w = 2.0 * np.pi * rate
    z = np.where(inside, -0.5 * depth * (1.0 - np.cos(w * tau)), 0.0)
    zdd = np.where(inside, -0.5 * depth * w * w * np.cos(w * tau), 0.0)
    record.pos[..., 2] += z
    record.acc[..., 2] += zdd


def build_trial(case: Case, preset: str, users: int, seed: int) -> Trial:
    """``users`` simulated users (seed ``seed``) through ``case`` and the IMU ``preset``."""
    rng = BatchRng([np.random.default_rng([seed, 31, i]) for i in range(users)])
    kw = {} if case.peak_g is None else {"peak_accel_g": (case.peak_g, case.peak_g)}
    params = MotionParams(imu_rate_hz=FS, control_rate_hz=CONTROL_HZ, **kw)
    intents, squats = case.plan(users, np.random.default_rng([seed, 37]))
    motion = UserMotion(params, rng)
    motion.reset()
    rec = MotionRecord.concatenate([motion.advance(i) for i in intents])
    if squats is not None:
        add_squats(rec, *squats)
    return sense_record(rec, rng, preset, FS)


def detected_times(spec: object, trial: Trial) -> list[NDArray[np.float64]]:
    """Heel-strike times (s, the record's clock) per user from step detector ``spec``, fed the
    trial's IMU samples and EKF attitude."""
    s = trial.imu
    b = s.acc.shape[0]
    stage = STEPS.build(spec, b, FS)
    if getattr(stage, "uses_position", False):  # the tracked headset: the head's position
        sigma = SensorConfig().headset_position_noise_m
        noise = np.random.default_rng([b, 41]).normal(0.0, sigma, trial.record.pos.shape)
        chunk = stage.update(s.acc, s.gyr, trial.q_est, position=trial.record.pos + noise)
    else:
        chunk = stage.update(s.acc, s.gyr, trial.q_est)
    users, _, peak = chunk.events()
    return [peak[users == i] + trial.record.t[0] for i in range(b)]


def count_steps(spec: object, trials: list[Trial]) -> Counts:
    """:class:`Counts` of ``spec`` pooled over every user of ``trials``."""
    out = Counts()
    for trial in trials:
        minutes = trial.record.t.size / FS / 60.0
        for det, true in zip(detected_times(spec, trial), trial.record.step_times, strict=True):
            out.add(true, det, minutes)
    return out


def seed_label(seeds: tuple[int, ...]) -> str:
    """ "development" if any seed is one of :data:`DEV_SEEDS`, else "held-out"."""
    return "development" if set(seeds) & set(DEV_SEEDS) else "held-out"


def simulated_table(
    seeds: tuple[int, ...],
    users: int,
    detectors: tuple[str, ...] | None = None,
    cases: tuple[Case, ...] = CASES,
) -> dict:
    """``{preset: {case: {detector: Counts.as_dict()}}}`` over ``seeds``."""
    names = tuple(STEPS.names()) if detectors is None else detectors
    out: dict = {}
    for preset in PRESETS:
        out[preset] = {}
        for case in cases:
            trials = [build_trial(case, preset, users, s) for s in seeds]
            out[preset][case.name] = {n: count_steps(n, trials).as_dict() for n in names}
    return out


# ------------------------------------------------------------------------- the Oxford recording
def tilt_quaternions(
    acc: NDArray[np.float64], fs: float, window_s: float = 1.0
) -> NDArray[np.float64]:
    """Sensor -> world quaternions (n, 4) that turn the running mean of the specific force over
    the last ``window_s`` seconds onto world up (yaw 0): an accelerometer-only attitude."""
    n = max(1, round(window_s * fs))
    csum = np.cumsum(np.vstack([np.zeros((1, 3)), acc]), axis=0)
    lo = np.maximum(np.arange(1, acc.shape[0] + 1) - n, 0)
    mean = (csum[1:] - csum[lo]) / (np.arange(1, acc.shape[0] + 1) - lo)[:, None]
    g = mean / np.linalg.norm(mean, axis=1, keepdims=True)
    axis = np.cross(g, [0.0, 0.0, 1.0])
    s = np.linalg.norm(axis, axis=1, keepdims=True)
    angle = np.arctan2(s[:, 0], g[:, 2])
    unit = np.divide(axis, s, out=np.zeros_like(axis), where=s > 1e-12)
    return quat_from_rotvec(unit * angle[:, None])


def _uniform(
    t: NDArray[np.float64], acc: NDArray[np.float64], fs: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The irregular samples averaged onto a uniform grid at ``fs`` (per axis, the bin mean of
    the linearly interpolated signal, as :func:`estimators.steps.offline.detect_steps` does for the
    norm)."""
    grid = t[0] + np.arange(int(np.floor((t[-1] - t[0]) * fs)) + 1) / fs
    return grid, np.stack([bin_average(t, acc[:, j], grid, fs) for j in range(3)], -1)


def oxford_detections(
    spec: object, t: NDArray[np.float64], acc: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Step times (s) of stage ``spec`` on irregular samples ``(t, acc)``: the uniform 100 Hz
    grid, the tilt attitude, zero angular rate; one second of the final mean force appended so
    that peaks near the end are judged."""
    grid, a = _uniform(t, acc, FS)
    pad = np.repeat(a[-round(FS) :].mean(axis=0, keepdims=True), round(FS), axis=0)
    a = np.vstack([a, pad])
    q = tilt_quaternions(a, FS)
    stage = STEPS.build(spec, 1, FS)
    _, _, peak = stage.update(a[None], np.zeros((1, *a.shape)), q[None]).events()
    return peak + grid[0]


def oxford_halves(duration: float, step_times: NDArray[np.float64]) -> tuple[float, float]:
    """The time (s) splitting the recording into two disjoint halves — the midpoint between the
    two true steps nearest the middle — and the duration; half 0 is ``t < split``, half 1
    ``t >= split``."""
    mid = 0.5 * duration
    k = int(np.searchsorted(step_times, mid))
    if 0 < k < step_times.size:
        mid = 0.5 * (step_times[k - 1] + step_times[k])
    return float(mid), float(duration)


def _score(true: NDArray[np.float64], det: NDArray[np.float64]) -> dict:
    """TP, FP, misses, true steps, F1 and the number detected, for one recording."""
    c = Counts()
    c.add(true, det, 0.0)
    out = c.as_dict()
    del out["user_minutes"], out["false_steps_per_min"]
    out["detected"] = int(det.size)
    return out


def two_fold_gamma(
    t: NDArray[np.float64],
    acc: NDArray[np.float64],
    step_times: NDArray[np.float64],
    grid_g: tuple[float, ...] = GAMMA_GRID_G,
) -> dict:
    """Choose the neck-pouch preset's gamma on one half of the recording, score it on the other.

    For each half: Zhang 2021's detector (``GaitParams.neck_pouch(gamma=...)``, offline
    :func:`estimators.steps.offline.detect_steps`) runs on that half's samples alone for every gamma
    of ``grid_g``; the best F1 wins (ties: the smallest gamma, the most sensitive, which keeps the
    lightest steps). The winner is scored on the other half, beside the preset's 0.15 g and the
    head default 0.07 g on that half; ``pooled_held_out`` sums the two evaluation halves.
    """
    split, _ = oxford_halves(float(t[-1] - t[0]), step_times)
    halves = [t < split, t >= split]
    truth = [step_times[step_times < split], step_times[step_times >= split]]
    f1 = np.empty((2, len(grid_g)))
    scores: list[list[dict]] = [[], []]
    for h in range(2):
        for j, g in enumerate(grid_g):
            det = detect_steps(
                t[halves[h]], acc[halves[h]], params=GaitParams.neck_pouch(gamma=g * GRAVITY)
            ).step_times
            s = _score(truth[h], det)
            scores[h].append(s)
            f1[h, j] = s["f1"]
    out: dict = {"split_s": round(split, 3), "grid_g": list(grid_g), "folds": []}
    preset_j = grid_g.index(0.15) if 0.15 in grid_g else None
    head_j = grid_g.index(0.07) if 0.07 in grid_g else None
    for tune in range(2):
        ev = 1 - tune
        best = min(range(len(grid_g)), key=lambda j: (-f1[tune, j], grid_g[j]))
        fold = {
            "tuned_on": f"half {tune}",
            "evaluated_on": f"half {ev}",
            "tuning_f1": {f"{g:.2f}": round(float(f1[tune, j]), 4) for j, g in enumerate(grid_g)},
            "chosen_gamma_g": grid_g[best],
            "held_out": scores[ev][best],
        }
        if preset_j is not None:
            fold["preset_0.15g_on_evaluation_half"] = scores[ev][preset_j]
        if head_j is not None:
            fold["head_0.07g_on_evaluation_half"] = scores[ev][head_j]
        out["folds"].append(fold)
    pooled = Counts()
    for fold in out["folds"]:
        h = fold["held_out"]
        pooled.tp += h["tp"]
        pooled.fp += h["fp"]
        pooled.misses += h["misses"]
        pooled.true_steps += h["true_steps"]
    out["pooled_held_out"] = {
        "tp": pooled.tp,
        "fp": pooled.fp,
        "misses": pooled.misses,
        "true_steps": pooled.true_steps,
        "f1": round(pooled.f1, 4),
    }
    return out


def oxford_table(folder: Path | None = None) -> dict | None:
    """Every detector on the Oxford neck-pouch walk (default: the one
    :func:`agents.recordings.data.data_path` finds, ``vrloco data fetch oxford``), and the two-fold
    gamma; None if absent."""
    if folder is None:
        try:
            folder = data_path("oxford")
        except DataMissing:
            return None
    if not folder.is_dir():
        return None
    rec = load_oxford(folder)
    truth = rec.step_times
    rows: dict = {}
    for name in STEPS.names():
        if getattr(STEPS.factory(name), "uses_position", False):
            continue  # a neck-pouch IMU: no tracked headset position to read
        rows[name] = {
            "label": "not tuned on this recording",
            **_score(truth, oxford_detections(name, rec.t, rec.acc)),
        }
    rows["zhang2021 neck_pouch"] = {
        "label": "in-sample (preset tuned on this recording)",
        **_score(truth, oxford_detections(GaitParams.neck_pouch(), rec.t, rec.acc)),
    }
    rows["zhang2021 neck_pouch (detect_steps)"] = {
        "label": "in-sample (preset tuned on this recording); vrloco estimate's path",
        **_score(truth, detect_steps(rec.t, rec.acc, params=GaitParams.neck_pouch()).step_times),
    }
    return {
        "recording": folder.name,
        "true_steps": int(truth.size),
        "duration_s": round(rec.duration, 2),
        "detectors": rows,
        "two_fold_gamma": two_fold_gamma(rec.t, rec.acc, truth),
    }


# ------------------------------------------------------------------------------------ reporting
def format_tables(result: dict) -> str:
    lines = [
        f"Step detectors outside the design envelope: {result['seed_label']} seeds "
        f"{tuple(result['seeds'])}, {result['users']} users each, EKF attitude, +-0.2 s "
        "matching; TP / FP / misses, F1, false steps per minute"
    ]
    for preset, cases in result["simulated"].items():
        lines.append(f"[{preset}]")
        for case, rows in cases.items():
            kind = "stepping" if result["stepping"].get(case, True) else "standing: no true step"
            lines.append(f"  {case} ({kind})")
            for name, r in rows.items():
                f1 = "  n/a" if r["f1"] is None else f"{r['f1']:.3f}"
                lines.append(
                    f"    {name:<12}{r['tp']:>5}{r['fp']:>5}{r['misses']:>5}   F1 {f1}"
                    f"   {r['false_steps_per_min']:6.1f}/min"
                )
    ox = result.get("oxford")
    if ox is None:
        lines.append(
            "Oxford recording absent: its figures skipped (`vrloco data fetch oxford` downloads it)"
        )
        return "\n".join(lines)
    lines.append(
        f"Oxford {ox['recording']} (CC-BY-4.0), {ox['true_steps']} foot-switch steps in "
        f"{ox['duration_s']:.0f} s; accelerometer only (tilt attitude, no gyro veto)"
    )
    for name, r in ox["detectors"].items():
        lines.append(
            f"  {name:<36}TP {r['tp']:>4} FP {r['fp']:>4} misses {r['misses']:>4} "
            f"F1 {r['f1']:.3f}  [{r['label']}]"
        )
    tf = ox["two_fold_gamma"]
    lines.append(f"  two-fold gamma of neck_pouch (split at {tf['split_s']} s), held-out half:")
    for fold in tf["folds"]:
        h = fold["held_out"]
        p = fold.get("preset_0.15g_on_evaluation_half")
        line = (
            f"    tuned on {fold['tuned_on']}: gamma {fold['chosen_gamma_g']:.2f} g -> "
            f"{fold['evaluated_on']} TP {h['tp']} FP {h['fp']} misses {h['misses']} "
            f"F1 {h['f1']:.3f}"
        )
        if p is not None:
            line += f" (preset 0.15 g there: F1 {p['f1']:.3f}, in-sample)"
        lines.append(line)
    p = tf["pooled_held_out"]
    lines.append(
        f"    both held-out halves: TP {p['tp']} FP {p['fp']} misses {p['misses']} F1 {p['f1']:.3f}"
    )
    return "\n".join(lines)


def run_step_envelope(
    json_path: Path | None = None,
    seed: int = HELD_OUT_SEEDS[0],
    dev: bool = False,
    users: int = 8,
    oxford: Path | None = None,
) -> dict:
    """The simulated cases and the Oxford tables (on ``oxford``, default the recording
    :func:`oxford_table` finds); prints them, writes JSON if asked.

    Raises:
        ValueError: ``users`` not an integer >= 1, or ``seed`` not an integer >= 0.
    """
    for name, value, lo in (("users", users, 1), ("seed", seed, 0)):
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < lo:
            raise ValueError(f"run_step_envelope: {name}={value!r} must be an integer >= {lo}")
    seeds = DEV_SEEDS if dev else (seed, seed + 1, seed + 2)
    result: dict = {
        "seeds": list(seeds),
        "seed_label": seed_label(seeds),
        "users": users,
        "stepping": {c.name: c.stepping for c in CASES},
        "simulated": simulated_table(seeds, users),
    }
    result["oxford"] = oxford_table(oxford)
    print(format_tables(result))
    if json_path is not None:
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(json.dumps(result, indent=2))
        print(f"wrote {json_path}")
    return result
