"""Speed of the stable-baselines3 PPO training loop, the default settings against vrloco's.

Run from the repository root::

    python benchmarks/bench_training.py             # about a minute on 2 idle cores
    python benchmarks/bench_training.py --busy 1    # beside a process that keeps a core busy
    python benchmarks/bench_training.py --busy 2    # beside two (about three minutes)
    python benchmarks/bench_training.py --env-alone 32,256,512   # and the env alone

Each run trains PPO from scratch (seed 0, :func:`agents.learned.train.defaults_ppo`: 256 steps x 32
users per rollout, minibatches of 2048, 5 epochs) on Approach for ``--iterations`` PPO
iterations in a fresh Python process, in one of two configurations:

* ``default``: the loop as stable-baselines3 runs it when torch is imported before vrloco's
  kernels (what ``agents.learned`` did before it imported :mod:`estimators.kernels` first):
  torch's OpenMP threads wait actively, and the rollouts' forward passes use torch's threads.
* ``one_thread``: ``default`` with torch on one thread once the model is built (its spinning
  OpenMP threads idle): the computation ``vrloco`` does, in the order ``vrloco`` does it.
* ``vrloco``: the loop of :func:`agents.learned.train.train_ppo`: ``agents.learned`` imported first
  (torch's OpenMP threads wait passively), rollouts and updates on one torch thread
  (:class:`agents.learned.train.OneTorchThread`), the same PPO settings.
* ``workers``: ``vrloco`` with the users stepped in ``--env-workers`` processes, a share of the
  batch each (``vrloco train --env-workers N``, :func:`agents.learned.parallel_env.parallel_users`).
* ``env_alone`` (with ``--env-alone N,N,...``): the task's vector env alone, random actions, no
  policy and no update, at each number of users: the most steps per second any trainer could
  reach with this env on this machine (a loop cannot step faster than its env).
* ``baseline`` (with ``--baseline REV``): the ``default`` loop run from a checkout of the git
  revision ``REV`` (a temporary worktree), its env and trainer as they were then: how much faster
  the whole loop per environment step is now than at ``REV``, on the same machine in one run.
  Its weights differ from the others' wherever the env's episodes changed since ``REV``.

The runs alternate (default, vrloco, default, vrloco, ...) so that other load on the machine
hits both alike; the table gives each configuration's median environment steps per second of
``model.learn`` and the median share of its time spent in the env (the vector env's ``reset``
and ``step`` behind the SB3 adapter), in the policy's forward pass (``collect_rollouts`` minus
the env), in the update (``train()``) and elsewhere. ``one_thread``, ``vrloco`` and ``workers``
must train the same weights: the script checks their SHA-256 and says whether they agree.
``default``'s update sums on torch's own thread count, in another order, so its weights differ
in the last bits where that count is not one. No evaluation, no checkpoints, no TensorBoard: the
loop alone.

A random policy's episodes run their whole horizon, so these iterations hardly reset a user and
hardly draw a room; a whole run, whose learner soon ends episodes early, also spends its time
drawing rooms and playing its evaluations, which ``benchmarks/profile_training.py`` times.

How much the vrloco configuration gains depends on the other load on the cores: actively
waiting OpenMP threads cost little while every core is free and a great deal while another
process holds one (each parallel region of the env's kernels then waits for a thread that has
no core). ``--busy N`` runs N spinning Python processes beside the runs, for a contended
machine that can be reproduced.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = ("default", "one_thread", "vrloco", "workers")


def timed(owner: object, name: str, spent: dict[str, float], key: str) -> None:
    """Add the time of every call of ``owner.name`` to ``spent[key]``."""
    call = getattr(owner, name)

    def wrapper(*args, **kwargs):
        t0 = time.perf_counter()
        try:
            return call(*args, **kwargs)
        finally:
            spent[key] += time.perf_counter() - t0

    setattr(owner, name, wrapper)


def child(
    config: str, task: str, num_envs: int, iterations: int, workers: int, root: Path = ROOT
) -> dict:
    """One training run in this process (a fresh one) from the tree ``root``: its timings
    and weights' hash."""
    if config in ("default", "one_thread", "baseline"):
        import torch  # first, as stable-baselines3 pulled it in before vrloco's kernels
    sys.path.insert(0, str(root))
    try:
        import agents.learned.train as learned  # in the vrloco configuration, before torch
    except ImportError:  # a baseline revision from before agents.learned was a package
        import agents.learned as learned

    # isort: split
    import hashlib

    import numpy as np
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecMonitor

    from vrloco_env.vector import VRLocoVectorEnv

    settings = learned.defaults_ppo()
    steps = iterations * settings["n_steps"] * num_envs
    if config == "workers":
        from agents.learned.models import env_settings
        from agents.learned.parallel_env import parallel_users

        env = parallel_users(num_envs, workers, env_settings(task))
    else:  # the task's default cell, as vrloco train builds it (env_settings(task))
        env = VRLocoVectorEnv(num_envs, task=task)
    env.reset(seed=0)  # load the compiled kernels before the clock starts; learn() reseeds
    env.step(np.zeros((num_envs, 5), np.float32))
    inner = learned.SB3VecEnv(env, seed=0)
    venv = VecMonitor(inner, info_keywords=("is_success",))
    if config in ("default", "one_thread", "baseline"):
        model = PPO("MlpPolicy", venv, seed=0, verbose=0, **settings)
        callback = None
        if config == "one_thread":
            torch.set_num_threads(1)
    else:
        model = learned.make_model(venv, seed=0, **settings)
        callback = learned.OneTorchThread()
    spent = {"env": 0.0, "collect": 0.0, "update": 0.0}
    timed(inner, "reset", spent, "env")
    timed(inner, "step_wait", spent, "env")
    timed(model, "collect_rollouts", spent, "collect")
    timed(model, "train", spent, "update")
    t0 = time.perf_counter()
    model.learn(steps, callback=callback)
    wall = time.perf_counter() - t0
    env.close()
    digest = hashlib.sha256()
    for p in model.policy.state_dict().values():
        digest.update(p.detach().cpu().numpy().tobytes())
    return {
        "config": config,
        "steps": int(model.num_timesteps),
        "wall_s": wall,
        "env_s": spent["env"],
        "forward_s": spent["collect"] - spent["env"],
        "update_s": spent["update"],
        "other_s": wall - spent["collect"] - spent["update"],
        "torch_threads": torch.get_num_threads(),
        "weights": digest.hexdigest(),
    }


def env_alone(task: str, num_envs: int, iterations: int, loop_users: int) -> dict:
    """The vector env of ``num_envs`` users alone (random actions, seeded) for as many user-steps
    as ``iterations`` PPO iterations of ``loop_users`` users take."""
    sys.path.insert(0, str(ROOT))
    import agents.learned.train as learned  # the trainer's thread settings

    user_steps = iterations * learned.defaults_ppo()["n_steps"] * loop_users

    # isort: split
    import numpy as np

    from vrloco_env.vector import VRLocoVectorEnv

    env = VRLocoVectorEnv(num_envs, task=task)
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    env.step(np.zeros((num_envs, 5), np.float32))  # the compiled kernels load
    steps = max(user_steps // num_envs, 1)
    actions = rng.uniform(-1.0, 1.0, (steps, num_envs, 5)).astype(np.float32)
    t0 = time.perf_counter()
    for a in actions:
        env.step(a)
    wall = time.perf_counter() - t0
    env.close()
    return {"config": f"env_alone:{num_envs}", "steps": steps * num_envs, "wall_s": wall}


def run(config: str, args: argparse.Namespace) -> dict:
    """:func:`child` in a fresh process, started without ``OMP_WAIT_POLICY`` (each
    configuration sets what it sets itself); the baseline's from its worktree."""
    env = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"}
    root = args.baseline_tree if config == "baseline" else ROOT
    cmd = [
        sys.executable,
        __file__,
        "--child",
        config,
        "--task",
        args.task,
        "--num-envs",
        str(args.num_envs),
        "--iterations",
        str(args.iterations),
        "--env-workers",
        str(args.env_workers),
        "--root",
        str(root),
    ]
    out = subprocess.run(cmd, env=env, cwd=root, capture_output=True, text=True, check=False)
    if out.returncode != 0:
        raise SystemExit(f"the {config} run failed:\n{out.stderr[-3000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def _user_counts(text: str) -> list[int]:
    """``--env-alone``'s numbers of users: integers >= 1 joined by commas."""
    try:
        counts = [int(n) for n in text.split(",")]
    except ValueError:
        counts = []
    if not counts or min(counts) < 1:
        raise argparse.ArgumentTypeError(
            f"{text!r}: give numbers of users >= 1 joined by commas, e.g. 32,256"
        )
    return counts


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--task", default="approach")
    parser.add_argument("--num-envs", type=int, default=32)
    parser.add_argument("--iterations", type=int, default=3, help="PPO iterations per run")
    parser.add_argument("--repeats", type=int, default=2, help="runs of each configuration")
    parser.add_argument(
        "--busy",
        type=int,
        default=0,
        metavar="N",
        help="keep N other processes busy during the runs",
    )
    parser.add_argument(
        "--env-workers", type=int, default=2, help="processes of the workers configuration"
    )
    parser.add_argument(
        "--baseline",
        metavar="REV",
        help="also time the default loop at this git revision (e.g. the commit a speed-up is "
        "measured against)",
    )
    parser.add_argument(
        "--env-alone",
        type=_user_counts,
        metavar="N,N,...",
        help="also time the env alone (random actions, no trainer) at these numbers of users",
    )
    parser.add_argument("--child", help=argparse.SUPPRESS)
    parser.add_argument("--root", type=Path, default=ROOT, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child and args.child.startswith("env_alone:"):
        n = int(args.child.split(":")[1])
        print(json.dumps(env_alone(args.task, n, args.iterations, args.num_envs)))
        return
    if args.child:
        print(
            json.dumps(
                child(
                    args.child,
                    args.task,
                    args.num_envs,
                    args.iterations,
                    args.env_workers,
                    args.root,
                )
            )
        )
        return
    busy = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(args.busy)]
    with tempfile.TemporaryDirectory() as tmp:
        args.baseline_tree = None
        if args.baseline:
            args.baseline_tree = Path(tmp) / "baseline"
            subprocess.run(
                ["git", "worktree", "add", "--detach", str(args.baseline_tree), args.baseline],
                cwd=ROOT,
                check=True,
                capture_output=True,
            )
        try:
            measure(args)
        finally:
            for process in busy:
                process.kill()
                process.wait()
            if args.baseline_tree is not None:
                subprocess.run(
                    ["git", "worktree", "remove", "--force", str(args.baseline_tree)],
                    cwd=ROOT,
                    check=False,
                    capture_output=True,
                )


def measure(args: argparse.Namespace) -> None:
    """The alternated runs and their table."""
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(
        f"PPO on {args.task}: {args.num_envs} users, {args.iterations} iterations per run, "
        f"{args.repeats} runs of each configuration alternated; {os.cpu_count()} cores, "
        f"load average {load:.2f} at the start"
        f"{f'; {args.busy} other processes kept busy' if args.busy else ''}"
    )
    configs = (*CONFIGS, "baseline") if args.baseline else CONFIGS
    if args.env_alone:
        configs = (*configs, *(f"env_alone:{n}" for n in args.env_alone))
    runs: dict[str, list[dict]] = {c: [] for c in configs}
    for i in range(args.repeats):
        for config in configs:
            r = run(config, args)
            runs[config].append(r)
            print(
                f"  run {i + 1} {config:<14} {r['steps'] / r['wall_s']:7.0f} steps/s  "
                f"({r['steps']:,} steps in {r['wall_s']:.1f} s)",
                flush=True,
            )
    print()
    print(
        f"{'':14} {'steps/s':>8}  {'env':>6} {'forward':>8} {'update':>7} {'other':>6}   "
        "(medians; shares of the loop's time)"
    )
    rate = {}
    for config in configs:
        rs = runs[config]
        rate[config] = statistics.median(r["steps"] / r["wall_s"] for r in rs)
        if config.startswith("env_alone"):
            print(f"{config:<14} {rate[config]:8.0f}  (the env alone: no forward pass, no update)")
            continue
        share = {
            k: statistics.median(r[f"{k}_s"] / r["wall_s"] for r in rs)
            for k in ("env", "forward", "update", "other")
        }
        print(
            f"{config:<14} {rate[config]:8.0f}  {share['env']:6.0%} {share['forward']:8.0%} "
            f"{share['update']:7.0%} {share['other']:6.0%}"
        )
    print(f"\nvrloco / default: {rate['vrloco'] / rate['default']:.2f}x the steps per second")
    print(
        f"workers ({args.env_workers} env processes) / default: "
        f"{rate['workers'] / rate['default']:.2f}x the steps per second"
    )
    if args.baseline:
        print(
            f"vrloco / baseline ({args.baseline}): {rate['vrloco'] / rate['baseline']:.2f}x the "
            "steps per second"
        )
        same = {r["weights"] for r in runs["baseline"]} == {r["weights"] for r in runs["vrloco"]}
        print(
            "the baseline trained "
            + ("the same weights" if same else "other weights (its episodes differ)")
        )
    alone = [c for c in configs if c.startswith("env_alone")]
    if alone:
        best = max(alone, key=rate.get)
        against = "baseline" if args.baseline else "default"
        print(
            f"the env alone at its fastest ({best.split(':')[1]} users): "
            f"{rate[best] / rate[against]:.2f}x the {against} loop's steps per second (no loop "
            "with this env can exceed it)"
        )
    digests = {r["weights"] for c in ("one_thread", "vrloco", "workers") for r in runs[c]}
    same = (
        "the same weights in every run"
        if len(digests) == 1
        else (f"DIFFERENT weights ({len(digests)} distinct)")
    )
    print(f"one_thread, vrloco and workers: {same} (SHA-256 {sorted(digests)[0][:16]}...)")
    default = {r["weights"] for r in runs["default"]}
    print(
        "default: "
        + (
            "the same weights"
            if default == digests
            else f"other weights ({torch_threads(runs['default'])} torch threads in its update "
            "against one: the same sums in another order)"
        )
    )


def torch_threads(runs: list[dict]) -> int:
    """The torch thread count of the runs (the most any of them had)."""
    return max(r["torch_threads"] for r in runs)


if __name__ == "__main__":
    main()
