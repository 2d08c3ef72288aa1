"""Zhang 2021's experiments in simulation, with ground truth the paper did not have.

* Fig. 3 / section 4.1: the five in-place head motions (serpentine, pitch, shake, spin, backward)
  with the IMU on the forehead. Attitude RMSE against the true attitude (yaw, pitch, roll) for both
  IMU presets, and — as the paper compared against the IMU's commercial on-board output (a mean
  deviation of 1.1e-2 deg) — the mean absolute deviation from a reference filter, VQF, run on the
  same samples.
* Fig. 2 / section 2: still/walk recognition and step detection. F1 against the true heel strikes
  (+-0.2 s) while stepping in place at 1.2, 1.7 and 2.2 steps/s, also with the head scanning; and
  phantom steps during the head-only motions.
* Figs. 4 and 5 / section 4.2: a straight walk in place, and a walk turning 45 deg away from an
  obstacle and back; true path (true steps, true heading) against eq (17) (detected steps,
  estimated heading) and the smooth-locomotion filter (the smooth-locomotion paper).

Run: ``vrloco experiment head-motions [--out DIR] [--json PATH] [--users N]``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from agents.benchmark.step_matching import step_f1
from estimators.attitude import estimate_attitude
from estimators.locomotion import SmoothLocomotion
from estimators.locomotion.dead_reckoning import dead_reckon
from estimators.rotations import angle_diff, quat_to_ypr
from estimators.steps import StepDetector
from vrloco_env.batch_rng import BatchRng
from vrloco_env.sensors.imu import HeadImu, ImuSamples, get_imu_spec
from vrloco_env.user import Intent, MotionParams, MotionRecord, UserMotion, run_script

HEAD_MOTIONS = ("serpentine", "pitch", "shake", "spin", "backward")
PRESETS = ("ig500n", "consumer_mems")
CADENCES = (1.2, 1.7, 2.2)
STEP_LENGTH = 0.7  # m, eq (17)'s SL
F1_TOLERANCE_S = 0.2
_WARMUP_S = 1.0  # left out of attitude statistics: filter initialisation


@dataclass
class Trial:
    """One scripted motion of B users through the IMU and the head estimators."""

    record: MotionRecord
    imu: ImuSamples
    q_est: np.ndarray  # (B, N, 4)
    steps_detected: list[np.ndarray]  # estimated heel-strike times per user (s, record clock)
    step_counts: np.ndarray  # (B, N) steps confirmed at each sample
    state: np.ndarray  # (B, N) still 0 / walk 1


def sense_record(record: MotionRecord, rng: BatchRng, preset: str, fs: float) -> Trial:
    """A true motion record through the head IMU ``preset`` at ``fs`` Hz, the Zhang 2021 EKF and
    step detector: the :class:`Trial` of every head-motion case."""
    imu = HeadImu(get_imu_spec(preset), rng, rate_hz=fs)
    s = imu.sample(record.quat, record.omega, record.acc, record.pos)
    q_est = estimate_attitude(s.gyr, s.acc, s.mag, fs)
    det = StepDetector(record.quat.shape[0], fs)
    out = det.update(s.acc)
    # The detector's clock counts samples from 0; the record's first sample is at 1/fs.
    b, _, peak = out.events()
    detected = [peak[b == i] + record.t[0] for i in range(record.quat.shape[0])]
    return Trial(record, s, q_est, detected, out.steps.astype(np.int64), out.state)


def run_trial(
    name: str, preset: str, users: int, seed: int, cadence: float = 1.7, fs: float = 100.0
) -> Trial:
    """Scripted motion ``name`` (see :func:`vrloco_env.user.motion.script_intents`) for
    ``users``."""
    rng = BatchRng([np.random.default_rng([seed, i]) for i in range(users)])
    params = MotionParams(imu_rate_hz=fs)
    rec = run_script(name, rng, params, cadence=cadence)
    return sense_record(rec, rng, preset, fs)


def stepping_with_head_scan(
    preset: str, users: int, seed: int, cadence: float, fs: float = 100.0
) -> Trial:
    """Stepping in place while looking around (head yaw +-30 deg at 0.3 Hz, pitch +-10 deg)."""
    rng = BatchRng([np.random.default_rng([seed, 7, i]) for i in range(users)])
    params = MotionParams(imu_rate_hz=fs)
    motion = UserMotion(params, rng)
    motion.reset()
    scan = Intent(
        cadence=cadence,
        gesture_amplitude=(np.deg2rad(30.0), np.deg2rad(10.0), 0.0),
        gesture_frequency=(0.3, 0.2, 0.3),
    )
    still = Intent(gesture_frequency=(0.3, 0.2, 0.3))
    plan = [still] * 20 + [scan] * 160 + [still] * 20
    rec = MotionRecord.concatenate([motion.advance(i) for i in plan])
    return sense_record(rec, rng, preset, fs)


def attitude_rmse(trial: Trial) -> dict[str, float]:
    """RMSE (deg) per ZYX angle over all users after the warm-up."""
    keep = trial.record.t >= _WARMUP_S
    est = quat_to_ypr(trial.q_est[:, keep])
    true = trial.record.ypr[:, keep]
    err = np.rad2deg(angle_diff(est, true))
    rmse = np.sqrt(np.mean(err**2, axis=(0, 1)))
    return {"yaw": float(rmse[0]), "pitch": float(rmse[1]), "roll": float(rmse[2])}


def vqf_deviation(trial: Trial, fs: float = 100.0) -> float | None:
    """Mean absolute Euler deviation (deg) of our attitude from VQF's on the same samples."""
    try:
        from vqf import offlineVQF
    except ImportError:  # vqf is in the optional 'bench' extra
        return None
    keep = trial.record.t >= _WARMUP_S
    devs = []
    for i in range(trial.q_est.shape[0]):  # VQF takes one stream at a time
        s = trial.imu
        ref = offlineVQF(
            np.ascontiguousarray(s.gyr[i]),
            np.ascontiguousarray(s.acc[i]),
            np.ascontiguousarray(s.mag[i]),
            1.0 / fs,
        )["quat9D"]
        d = angle_diff(quat_to_ypr(trial.q_est[i, keep]), quat_to_ypr(ref[keep]))
        devs.append(np.mean(np.abs(np.rad2deg(d))))
    return float(np.mean(devs))


def step_scores(trial: Trial) -> dict[str, float]:
    """Pooled precision, recall and F1 (+-0.2 s) and the counts of true and detected steps."""
    tp = n_det = n_true = 0
    for det, true in zip(trial.steps_detected, trial.record.step_times, strict=True):
        precision, _, _ = step_f1(det, true, tol=F1_TOLERANCE_S)
        tp += round(precision * det.size)  # matched pairs
        n_det += det.size
        n_true += true.size
    precision = tp / n_det if n_det else 1.0
    recall = tp / n_true if n_true else 1.0
    f1 = 2 * precision * recall / (precision + recall) if precision + recall else 0.0
    return {
        "precision": precision,
        "recall": recall,
        "f1": f1,
        "true_steps": int(n_true),
        "detected_steps": int(n_det),
    }


def trajectories(trial: Trial, fs: float = 100.0) -> dict[str, np.ndarray]:
    """True path, eq (17) path and smooth path of user 0 (m, (N, 2) each)."""
    rec = trial.record
    yaw_true = rec.ypr[0, :, 0]
    yaw_est = quat_to_ypr(trial.q_est[0])[:, 0]
    true = dead_reckon(rec.step[0].astype(float), yaw_true, STEP_LENGTH)
    eq17 = dead_reckon(trial.step_counts[0].astype(float), yaw_est, STEP_LENGTH)
    smooth = SmoothLocomotion(1, STEP_LENGTH)
    path = np.empty((rec.t.size, 2))
    for k in range(rec.t.size):
        path[k] = smooth.update(trial.step_counts[0, k : k + 1], yaw_est[k : k + 1], 1.0 / fs)[0]
    return {"true": true, "eq17": eq17, "smooth": path}


def run_head_motions(
    out_dir: Path | None = None, json_path: Path | None = None, users: int = 8, seed: int = 0
) -> dict:
    """All of the above; prints tables, writes figures and JSON."""
    result: dict = {"users": users, "seed": seed, "attitude": {}, "steps": {}, "phantom": {}}
    fig3_trials = {}
    for preset in PRESETS:
        result["attitude"][preset] = {}
        for k, name in enumerate(HEAD_MOTIONS):
            trial = run_trial(name, preset, users, seed + 100 * k)
            row = {"rmse_deg": attitude_rmse(trial), "vqf_mean_deviation_deg": vqf_deviation(trial)}
            result["attitude"][preset][name] = row
            if preset == PRESETS[0]:
                fig3_trials[name] = trial
            if name in ("serpentine", "pitch", "shake"):
                result["phantom"].setdefault(preset, {})[name] = int(
                    sum(d.size for d in trial.steps_detected)
                )
        result["steps"][preset] = {}
        for c in CADENCES:
            plain = step_scores(run_trial("straight", preset, users, seed + 7, cadence=c))
            scan = step_scores(stepping_with_head_scan(preset, users, seed + 11, cadence=c))
            result["steps"][preset][f"{c:.1f}"] = {"straight": plain, "head_scan": scan}
    walks = {name: run_trial(name, "ig500n", 1, seed + 3) for name in ("straight", "avoid")}
    paths = {name: trajectories(t) for name, t in walks.items()}
    result["trajectories"] = {
        name: {k: [float(v) for v in p[-1]] for k, p in ps.items()} for name, ps in paths.items()
    }
    print(format_tables(result))
    if out_dir is not None:
        written = draw_figures(out_dir, fig3_trials, walks, paths)
        for p in written:
            print(f"wrote {p}")
    if json_path is not None:
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(json.dumps(result, indent=2))
        print(f"wrote {json_path}")
    return result


def format_tables(result: dict) -> str:
    lines = [
        f"Zhang 2021 head motions, simulated ({result['users']} users each), attitude RMSE vs "
        "truth (deg) and mean deviation from VQF (deg; the paper: 1.1e-2 vs the IMU's "
        "own filter)"
    ]
    lines.append(f"  {'preset':<14}{'motion':<12}{'yaw':>7}{'pitch':>7}{'roll':>7}{'vs VQF':>9}")
    for preset, rows in result["attitude"].items():
        for name, row in rows.items():
            r = row["rmse_deg"]
            dev = row["vqf_mean_deviation_deg"]
            dev_s = f"{dev:9.3f}" if dev is not None else "      n/a"
            lines.append(
                f"  {preset:<14}{name:<12}{r['yaw']:7.2f}{r['pitch']:7.2f}{r['roll']:7.2f}{dev_s}"
            )
    lines.append("Step detection, F1 vs true heel strikes (+-0.2 s): straight / with head scan")
    for preset, rows in result["steps"].items():
        cells = "  ".join(
            f"{c} Hz {v['straight']['f1']:.3f} / {v['head_scan']['f1']:.3f}"
            for c, v in rows.items()
        )
        lines.append(f"  {preset:<14}{cells}")
    for preset, rows in result["phantom"].items():
        cells = ", ".join(f"{k} {v}" for k, v in rows.items())
        lines.append(f"  phantom steps while standing ({preset}): {cells}")
    lines.append("Virtual path end points (m): true steps & heading / eq (17) / smooth")
    for name, ends in result["trajectories"].items():
        cells = "  ".join(f"{k} ({v[0]:.2f}, {v[1]:.2f})" for k, v in ends.items())
        lines.append(f"  {name:<10}{cells}")
    return "\n".join(lines)


def draw_figures(
    out_dir: Path,
    fig3: dict[str, Trial],
    walks: dict[str, Trial],
    paths: dict[str, dict[str, np.ndarray]],
) -> list[Path]:
    """Fig. 3 (attitude traces), Fig. 2 (gait) and Figs. 4/5 (paths) analogues."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    written = []

    fig, axes = plt.subplots(
        3, len(fig3), figsize=(16, 7), sharex="col", squeeze=False, constrained_layout=True
    )
    for j, (name, trial) in enumerate(fig3.items()):
        t = trial.record.t
        true = np.rad2deg(np.unwrap(trial.record.ypr[0], axis=0))
        est = np.rad2deg(np.unwrap(quat_to_ypr(trial.q_est[0]), axis=0))
        for i, label in enumerate(("yaw", "pitch", "roll")):
            ax = axes[i, j]
            ax.plot(t, true[:, i], color="0.6", lw=2.2, label="truth")
            ax.plot(t, est[:, i], color="k", lw=0.8, label="error-state EKF")
            if j == 0:
                ax.set_ylabel(f"{label} (deg)")
            if i == 0:
                ax.set_title(name)
        axes[-1, j].set_xlabel("time (s)")
    axes[0, 0].legend(fontsize=8)
    fig.suptitle(
        "Head attitude during Zhang 2021's five motions (ig500n, 100 Hz): estimate vs truth"
    )
    written.append(out_dir / "fig3_attitude.png")
    fig.savefig(written[-1], dpi=110)
    plt.close(fig)

    trial = walks["avoid"]
    t = trial.record.t
    fnorm = np.linalg.norm(trial.imu.acc[0], axis=-1)
    fig, ax = plt.subplots(figsize=(12, 3.8), constrained_layout=True)
    ax.plot(t, fnorm, lw=0.8, color="k", label="|f| (m/s²)")
    ax.fill_between(
        t,
        fnorm.min(),
        fnorm.max(),
        where=trial.state[0] > 0,
        color="tab:green",
        alpha=0.12,
        label="detected: walk",
    )
    true = trial.record.step_times[0]
    ax.plot(true, np.interp(true, t, fnorm) + 0.4, "v", color="tab:red", ms=5, label="true steps")
    det = trial.steps_detected[0]
    ax.plot(
        det, np.interp(det, t, fnorm) + 0.9, "v", color="tab:blue", ms=5, label="detected steps"
    )
    ax.set_xlabel("time (s)")
    ax.set_ylabel("|f| (m/s²)")
    ax.set_ylim(fnorm.min() - 0.3, fnorm.max() + 1.6)
    ax.legend(fontsize=8, loc="center left", bbox_to_anchor=(1.0, 0.5))
    ax.set_title("Still / walk recognition and step events (Zhang 2021 Fig. 2 analogue)")
    written.append(out_dir / "fig2_gait.png")
    fig.savefig(written[-1], dpi=110)
    plt.close(fig)

    fig, axes = plt.subplots(1, 2, figsize=(12, 5), constrained_layout=True)
    titles = (
        ("straight", "Fig. 4: straight walk in place"),
        ("avoid", "Fig. 5: turn away and back"),
    )
    for ax, (name, title) in zip(axes, titles, strict=True):
        ps = paths[name]
        ax.plot(*ps["true"].T, color="0.6", lw=3, label="true steps and heading")
        ax.plot(*ps["eq17"].T, "o-", color="tab:red", ms=3, lw=0.8, label="eq (17)")
        ax.plot(*ps["smooth"].T, color="tab:blue", lw=1.2, label="smooth")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x east (m)")
        ax.set_ylabel("y north (m)")
        ax.set_title(title)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8, loc="lower right")
    written.append(out_dir / "fig4_fig5_paths.png")
    fig.savefig(written[-1], dpi=110)
    plt.close(fig)
    return written
