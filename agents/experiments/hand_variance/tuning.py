"""The tuning rules of :mod:`agents.experiments.hand_variance` on the development seeds
(``DEV_STATIC_SEEDS``, ``DEV_MOVING_SEEDS`` of :mod:`~agents.experiments.hand_variance.settings`):
the development trials and scores, one grid per tuned hand filter (Yao 2023's Kalman
``accel_psd``, the adaptive Kalman filter, the One Euro filter) and :func:`run_tuning`, which
prints each rule's choice (``python -m agents.experiments.hand_variance``).
"""

from __future__ import annotations

import itertools

import numpy as np
from numpy.typing import NDArray

from agents.experiments.hand_variance.scores import moving_scores, static_scores
from agents.experiments.hand_variance.settings import _FS, DEV_MOVING_SEEDS, DEV_STATIC_SEEDS
from agents.experiments.hand_variance.trials import HandTrial, moving_trial, static_trial
from estimators.hand import HandParams, KalmanParams, OrientationFilter
from estimators.hand.adaptive import AdaptiveKalmanHandParams
from estimators.hand.one_euro import OneEuroHandParams

__all__ = [
    "development_scores",
    "development_trials",
    "run_tuning",
    "tune_adaptive_kalman",
    "tune_one_euro",
    "tune_yao2023_accel_psd",
]


def development_trials() -> tuple[list[HandTrial], list[HandTrial]]:
    """The development trials: static (11 angles x 5 repeats x 10 s) for each of
    :data:`DEV_STATIC_SEEDS`, moving (10 users x 10 s at 90 deg/s) for each of
    :data:`DEV_MOVING_SEEDS`."""
    return (
        [static_trial(5, s) for s in DEV_STATIC_SEEDS],
        [moving_trial(10, s) for s in DEV_MOVING_SEEDS],
    )


def development_scores(static: list[HandTrial], moving: list[HandTrial], run) -> dict:
    """Scores of a filter ``run(trial) -> (B, N, 3)`` on the development trials, against raw:
    ``rest_ratio`` and ``moving_ratio`` (seeds, 3) RMSE / raw's RMSE, ``rest_reduction`` (seeds,
    3) pooled variance reduction (%), ``mean_ratio`` the mean of all ratios."""
    rest, red, mov = [], [], []
    for tr in static:
        sc = static_scores(tr, {"raw": tr.frames.ypr_raw, "f": run(tr)})
        raw = np.array(list(sc["rmse_deg"]["raw"].values()))
        rest.append(np.array(list(sc["rmse_deg"]["f"].values())) / raw)
        red.append(list(sc["reduction_pct"]["f"].values()))
    for tr in moving:
        sc = moving_scores(tr, {"raw": tr.frames.ypr_raw, "f": run(tr)})
        raw = np.array(list(sc["raw"]["rmse_deg"].values()))
        mov.append(np.array(list(sc["f"]["rmse_deg"].values())) / raw)
    rest_a, mov_a = np.array(rest), np.array(mov)
    return {
        "rest_ratio": rest_a,
        "moving_ratio": mov_a,
        "rest_reduction": np.array(red),
        "mean_ratio": float(np.mean(np.concatenate([rest_a, mov_a]))),
    }


def _angles(trial: HandTrial, params: HandParams, output: str = "ypr") -> NDArray[np.float64]:
    fr = trial.frames
    out = OrientationFilter(fr.ypr.shape[0], params).update_angles(
        fr.ypr_raw, fr.quat_valid, fr.reselected
    )
    return getattr(out, output)


def tune_yao2023_accel_psd(
    static: list[HandTrial],
    moving: list[HandTrial],
    grid: tuple[float, ...] = (0.03, 0.1, 0.3, 1.0, 3.0, 10.0),
) -> list[tuple[float, dict]]:
    """Yao 2023's ``KalmanParams.accel_psd``: the development scores of the Kalman output (the
    other fields at their defaults, ``max_accel_psd`` raised to ``accel_psd`` where below it);
    the rule takes the smallest ``mean_ratio``."""
    rows = []
    for q in grid:
        params = HandParams(kalman=KalmanParams(accel_psd=q, max_accel_psd=max(10.0, q)))
        rows.append(
            (
                q,
                development_scores(
                    static, moving, lambda tr, p=params: _angles(tr, p, "ypr_kalman")
                ),
            )
        )
    return rows


def tune_adaptive_kalman(
    static: list[HandTrial], moving: list[HandTrial]
) -> list[tuple[tuple[float, float, float], dict]]:
    """:class:`estimators.hand.adaptive.AdaptiveKalmanHandParams`: development scores over its
    grid; the rule takes the smallest ``mean_ratio`` among settings with every ratio below 1."""
    rows = []
    for q, q_max, tau in itertools.product(
        (0.3, 1.0, 3.0, 10.0), (30.0, 100.0, 1000.0), (1.0 / 30.0, 0.05, 0.1)
    ):
        stage = AdaptiveKalmanHandParams(accel_psd=q, max_accel_psd=q_max, adapt_time=tau)
        params = stage.hand_params(_FS)
        rows.append(
            (
                (q, q_max, tau),
                development_scores(static, moving, lambda tr, p=params: _angles(tr, p)),
            )
        )
    return rows


def tune_one_euro(
    static: list[HandTrial], moving: list[HandTrial]
) -> list[tuple[tuple[float, float, float], dict]]:
    """:class:`estimators.hand.one_euro.OneEuroHandParams`: development scores over its grid;
    the rule (module docstring there) takes the largest worst-axis mean ``rest_reduction`` among
    settings whose swept-axis ``moving_ratio`` is below 0.97 on every seed."""
    rows = []
    grid = itertools.product(
        (0.3, 0.5, 0.7, 1.0, 1.5, 2.0, 3.0, 4.0, 5.0, 6.0),
        (0.5, 1.0, 2.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 40.0),
        (0.15, 0.25, 0.35, 0.5, 1.0, 2.0),
    )
    for mc, beta, dc in grid:
        p = OneEuroHandParams(min_cutoff=mc, beta=beta, d_cutoff=dc)

        def run(tr: HandTrial, p: OneEuroHandParams = p) -> NDArray[np.float64]:
            stage = p.build(tr.frames.ypr.shape[0], _FS)
            return np.concatenate([stage.update(f)[0] for f in tr.step_frames()], axis=1)

        rows.append(((mc, beta, dc), development_scores(static, moving, run)))
    return rows


def run_tuning(which: tuple[str, ...] = ("yao2023", "adaptive_kalman", "one_euro")) -> dict:
    """Print each rule's grid and choice on the development seeds (the One Euro grid, 600
    settings, takes some minutes); returns the chosen settings."""
    static, moving = development_trials()
    chosen: dict = {}
    print(f"development seeds: static {DEV_STATIC_SEEDS}, moving {DEV_MOVING_SEEDS} (in-sample)")
    if "yao2023" in which:
        rows = tune_yao2023_accel_psd(static, moving)
        print("Yao 2023 KalmanParams.accel_psd: mean RMSE ratio of the Kalman output")
        for q, sc in rows:
            print(
                f"  {q:8.3f}  {sc['mean_ratio']:.4f}  rest reduction "
                f"{np.round(sc['rest_reduction'].mean(axis=0), 1)}"
            )
        chosen["yao2023"] = min(rows, key=lambda r: r[1]["mean_ratio"])[0]
    if "adaptive_kalman" in which:
        rows = tune_adaptive_kalman(static, moving)
        ok = [r for r in rows if max(r[1]["rest_ratio"].max(), r[1]["moving_ratio"].max()) < 1.0]
        print("adaptive Kalman (accel_psd, max_accel_psd, adapt_time): mean RMSE ratio")
        for key, sc in sorted(ok, key=lambda r: r[1]["mean_ratio"])[:5]:
            print(f"  {key}  {sc['mean_ratio']:.4f}")
        chosen["adaptive_kalman"] = min(ok, key=lambda r: r[1]["mean_ratio"])[0]
    if "one_euro" in which:
        rows = tune_one_euro(static, moving)
        ok = [r for r in rows if r[1]["moving_ratio"][:, 0].max() < 0.97]
        print("One Euro (min_cutoff, beta, d_cutoff): worst-axis rest reduction, swept ratio")
        best = sorted(ok, key=lambda r: -r[1]["rest_reduction"].mean(axis=0).min())
        for key, sc in best[:5]:
            print(
                f"  {key}  {sc['rest_reduction'].mean(axis=0).min():.2f} %  "
                f"{sc['moving_ratio'][:, 0].max():.3f}"
            )
        chosen["one_euro"] = best[0][0]
    print(f"chosen: {chosen}")
    return chosen
