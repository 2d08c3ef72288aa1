"""The ``vrloco`` argument parser: the shared argument types (checked before any work starts)
and :func:`build_parser`, the tree of subcommands, each bound to its command function."""

from __future__ import annotations

import argparse
import dataclasses
import math
from pathlib import Path

from agents.cli.benchmark import cmd_benchmark
from agents.cli.experiments import (
    cmd_hand_variance,
    cmd_head_behaviour,
    cmd_head_motions,
    cmd_learned_ranking,
    cmd_locomotion,
    cmd_population_sensitivity,
    cmd_published,
    cmd_step_envelope,
    cmd_vio,
)
from agents.cli.learned import cmd_evaluate, cmd_train
from agents.cli.overview import cmd_demo, cmd_techniques
from agents.cli.recordings import cmd_data, cmd_estimate, cmd_record
from vrloco_env import __version__
from vrloco_env.config import RewardConfig


class _Help(argparse.ArgumentDefaultsHelpFormatter):
    """Help that shows each option's default (unless it has none or says it already)."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        if action.default is None or "default" in (action.help or ""):
            return action.help
        return super()._get_help_string(action)


def _int_at_least(lo: int):
    """An argparse type: an integer >= ``lo``."""

    def convert(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if value < lo:
            raise argparse.ArgumentTypeError(f"{value} must be >= {lo}")
        return value

    return convert


def _positive_float(text: str) -> float:
    """An argparse type: a finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value) or value <= 0.0:
        raise argparse.ArgumentTypeError(f"{value} must be a finite number > 0")
    return value


def _integers(text: str, example: str) -> list[int]:
    """The comma-separated integers of ``text``; an argparse error naming the part that is not
    one, with ``example`` of the form."""
    values = []
    for part in text.split(","):
        try:
            values.append(int(part))
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"{part.strip()!r} is not an integer (give them like {example})"
            ) from None
    return values


def _layer_sizes(text: str) -> list[int]:
    """An argparse type: comma-separated hidden layer sizes, each an integer in [1, 4096]
    (``256,256``)."""
    sizes = _integers(text, "256,256")
    for size in sizes:
        if not 1 <= size <= 4096:
            raise argparse.ArgumentTypeError(f"layer size {size} must be in [1, 4096]")
    return sizes


def _seed_list(text: str) -> list[int]:
    """An argparse type: comma-separated distinct integers >= 0 (``0,1,2``)."""
    seeds = _integers(text, "0,1,2")
    for i, seed in enumerate(seeds):
        if seed < 0:
            raise argparse.ArgumentTypeError(f"{seed} must be >= 0")
        if seed in seeds[:i]:
            raise argparse.ArgumentTypeError(f"seed {seed} is given twice")
    return seeds


def _reward_terms(text: str) -> RewardConfig:
    """An argparse type: ``TERM=W,...`` over the default :class:`RewardConfig`."""
    terms: dict[str, float | bool] = {}
    names = [f.name for f in dataclasses.fields(RewardConfig)]
    for part in text.split(","):
        name, sep, value = part.partition("=")
        name = name.strip()
        if not sep or name not in names:
            raise argparse.ArgumentTypeError(
                f"{part.strip()!r}: give TERM=WEIGHT with TERM one of {', '.join(names)}"
            )
        if name == "success_without_collision":
            if value.strip() not in ("true", "false"):
                raise argparse.ArgumentTypeError(f"{name}={value.strip()!r}: true or false")
            terms[name] = value.strip() == "true"
            continue
        try:
            terms[name] = float(value)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name}={value.strip()!r}: not a number") from None
    try:
        return RewardConfig(**terms)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def _preset(text: str) -> str:
    """An argparse type: an IMU preset name."""
    from vrloco_env.sensors.imu import get_imu_spec

    try:
        get_imu_spec(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None
    return text


def _task(text: str) -> str:
    """An argparse type: a registered task."""
    from vrloco_env.tasks import get_task

    try:
        get_task(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None
    return text


def _out_dir(text: str) -> str:
    """An argparse type: a folder that can be written (created if need be), checked before the
    work starts."""
    import tempfile

    path = Path(text)
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"{text!r} is a file, not a folder")
    try:
        path.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=path):
            pass
    except OSError as err:
        raise argparse.ArgumentTypeError(f"cannot write to {text!r}: {err.strerror}") from None
    return text


def _out_file(text: str) -> str:
    """An argparse type: a file whose folder can be written (checked before the work)."""
    path = Path(text)
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{text!r} is a folder, not a file")
    _out_dir(str(path.parent if str(path.parent) else "."))
    return text


def build_parser() -> argparse.ArgumentParser:
    from agents.benchmark.conditions import CONDITIONS
    from agents.benchmark.grid import (
        DEFAULT_BATCH_SIZE,
        DEFAULT_EPISODES,
        DEFAULT_POLICIES,
        DEFAULT_TASKS,
        DEFAULT_TECHNIQUES,
    )
    from agents.scripted import POLICIES
    from vrloco_env.sensors.imu.spec import PRESETS
    from vrloco_env.tasks import TASKS
    from vrloco_env.user.population import POPULATIONS

    parser = argparse.ArgumentParser(
        prog="vrloco",
        description="Hands-free VR locomotion: simulated users, sensors, estimators, benchmark.",
    )
    parser.add_argument("--version", action="version", version=f"vrloco {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub_add = sub.add_parser

    def add_parser(*a, **kw):  # every subcommand's --help shows the defaults
        return sub_add(*a, formatter_class=_Help, **kw)

    sub.add_parser = add_parser  # type: ignore[method-assign]

    demo = sub.add_parser(
        "demo",
        help="synthetic head-IMU trace of standing, stepping in place and turning (a figure)",
    )
    demo.add_argument("--out", default="out", type=_out_dir, help="folder for the figure")
    demo.add_argument("--seed", type=int, default=0, help="random seed")
    demo.add_argument(
        "--sensors", default="ig500n", type=_preset, help="IMU preset: ig500n or consumer_mems"
    )
    demo.set_defaults(func=cmd_demo)

    exp = sub.add_parser("experiment", help="reproduce a source paper's experiment")
    exp_sub = exp.add_subparsers(dest="experiment", metavar="EXPERIMENT", required=True)
    exp_add = exp_sub.add_parser
    exp_sub.add_parser = lambda *a, **kw: exp_add(  # type: ignore[method-assign]
        *a, formatter_class=_Help, **kw
    )
    hm = exp_sub.add_parser(
        "head-motions",
        help="Zhang 2021: attitude on five head motions, step detection, Fig. 2-5 analogues",
    )
    hm.add_argument("--out", default="out", type=_out_dir, help="folder for the figures")
    hm.add_argument("--json", type=_out_file, help="write the results to this JSON file")
    hm.add_argument("--users", type=_int_at_least(1), default=8, help="simulated users per case")
    hm.add_argument("--seed", type=int, default=0, help="random seed")
    hm.set_defaults(func=cmd_head_motions)
    se = exp_sub.add_parser(
        "step-envelope",
        help="every step detector on light steps, heavy nods, squats, looking down, scanning; "
        "and on the Oxford neck-pouch walk (in-sample and two-fold held-out)",
    )
    se.add_argument("--json", type=_out_file, help="write the results to this JSON file")
    se.add_argument(
        "--seed",
        type=_int_at_least(0),
        default=1000,
        help="first of three held-out seeds (seeds 0-2 are development seeds)",
    )
    se.add_argument("--dev", action="store_true", help="development seeds 0-2 instead")
    se.add_argument("--users", type=_int_at_least(1), default=8, help="simulated users per case")
    se.set_defaults(func=cmd_step_envelope)
    pub = exp_sub.add_parser(
        "published",
        help="published user-study findings (head tilt, VR-STEP, Lee 2018, gaze vs hand "
        "steering, hip steering, stop latency) reproduced on held-out seeds, with their tests",
    )
    pub.add_argument("--json", type=_out_file, help="write the results to this JSON file")
    pub.add_argument(
        "--episodes",
        type=_int_at_least(2),
        help="reporting episodes per cell (default: all 60 reporting seeds)",
    )
    pub.add_argument("--findings", help="comma-separated finding ids (default: all)")
    pub.add_argument(
        "--dev",
        action="store_true",
        help="the development seeds instead (in-sample: what the scenarios were chosen on)",
    )
    pub.set_defaults(func=cmd_published)
    lr = exp_sub.add_parser(
        "learned-ranking",
        help="the default grid's techniques ranked by the goal seeker, the shipped learned user "
        "and the user adapted to each technique, side by side, with paired tests",
    )
    lr.add_argument("--json", type=_out_file, help="write the results to this JSON file")
    lr.add_argument(
        "--episodes", type=_int_at_least(2), default=60, help="episodes per cell (seeds)"
    )
    lr.add_argument(
        "--adapt",
        type=_int_at_least(1),
        default=200_000,
        metavar="STEPS",
        help="the adapted user's fine-tuning steps on each technique",
    )
    lr.add_argument(
        "--adapt-seed",
        type=_int_at_least(0),
        default=0,
        metavar="SEED",
        help="the fine-tuning's random seed (another seed: another adapted user)",
    )
    lr.add_argument(
        "--dev",
        action="store_true",
        help="the development seeds (from 1000) instead of the reporting seeds (from 200000)",
    )
    lr.set_defaults(func=cmd_learned_ranking)
    hb = exp_sub.add_parser(
        "head-behaviour",
        help="head-motion statistics of every user population, standing and walking, beside "
        "held-out real head traces of people viewing 360-degree video (not walking)",
    )
    hb.add_argument("--json", type=_out_file, help="write the results to this JSON file")
    hb.add_argument(
        "--episodes",
        type=_int_at_least(1),
        default=16,
        help="simulated users per population and condition",
    )
    hb.add_argument("--seed", type=_int_at_least(0), default=0, help="first episode's seed")
    hb.add_argument(
        "--out",
        type=_out_dir,
        help="folder for the figure (default: beside --json; neither: no figure)",
    )
    hb.set_defaults(func=cmd_head_behaviour)
    ps = exp_sub.add_parser(
        "population-sensitivity",
        help="the default benchmark's pair verdicts with each chosen population range (a choice "
        "in its doc) collapsed to its low or high end",
    )
    ps.add_argument("--json", type=_out_file, help="write the results to this JSON file")
    ps.add_argument(
        "--episodes",
        type=_int_at_least(1),
        default=60,
        help="episodes per cell (seeds 0 to N-1, as the default benchmark)",
    )
    ps.add_argument("--fields", help="comma-separated choice fields (default: every one)")
    ps.add_argument(
        "--out",
        type=_out_dir,
        help="folder for each run's rows, reused by a rerun (default: a temp folder)",
    )
    ps.set_defaults(func=cmd_population_sensitivity)
    hv = exp_sub.add_parser(
        "hand-variance",
        help="Yao 2023 Tables 1-4 on the synthetic Kinect, with lag and RMSE while moving",
    )
    hv.add_argument("--json", type=_out_file, help="write the results to this JSON file")
    hv.add_argument("--repeats", type=_int_at_least(1), default=10, help="repeats per angle")
    hv.add_argument("--seed", type=int, default=0, help="random seed")
    hv.set_defaults(func=cmd_hand_variance)
    vio = exp_sub.add_parser(
        "vio",
        help="the helmet-tracking paper: IMU-only drift, visual-only and fused helmet pose, "
        "adaptive vs fixed R",
    )
    vio.add_argument("--json", type=_out_file, help="write the results to this JSON file")
    vio.add_argument("--duration", type=float, default=120.0, help="length of every run, s")
    vio.add_argument("--seed", type=int, default=0, help="random seed")
    vio.add_argument("--out", type=_out_dir, help="folder for the error-vs-time figure")
    vio.add_argument("--workers", type=int, default=2, help="threads for the PnP solves")
    vio.set_defaults(func=cmd_vio)
    loco = exp_sub.add_parser(
        "locomotion",
        help="eq (17) vs the smooth-locomotion paper's filter: distance and jerk",
    )
    loco.add_argument("--json", type=_out_file, help="write the results to this JSON file")
    loco.set_defaults(func=cmd_locomotion)
    bench = sub.add_parser(
        "benchmark",
        help="simulated users x tasks x techniques: outcomes, walking-in-place measures, "
        "collision causes, paired tests",
        description="Without --tasks, --policies, --techniques, --sensors and --conditions: the "
        "default run (agents.benchmark.DEFAULT_GRIDS: the main grid and the scenarios where a "
        "technique should differ from zhang2021), then the discriminating-power table "
        "(agents.benchmark.discrimination). Given some of them: their one grid, the others from "
        "the main grid.",
    )
    bench.add_argument(
        "--tasks",
        help=f"comma-separated tasks: {', '.join(TASKS)} (main grid: {','.join(DEFAULT_TASKS)})",
    )
    bench.add_argument(
        "--policies",
        help=f"comma-separated users: {', '.join(POLICIES)}, ppo (the task's shipped learned "
        "user), a stable-baselines3 .zip or 'module:attr'; append "
        f"+<population> ({', '.join(POPULATIONS)}) for a human population "
        f"(main grid: {','.join(DEFAULT_POLICIES)})",
    )
    bench.add_argument(
        "--adapt",
        type=_int_at_least(0),
        metavar="STEPS",
        help="fine-tune a copy of the shipped learned user (ppo) on each cell for STEPS "
        "environment steps before playing it (seeded, the same budget for every technique, "
        "cached: a rerun reuses it; 0: no adaptation)",
    )
    bench.add_argument(
        "--techniques",
        help="comma-separated techniques (vrloco techniques lists them; 'module:attr' names "
        f"your own); main grid: {','.join(DEFAULT_TECHNIQUES)} unless --sensors is given",
    )
    bench.add_argument(
        "--sensors",
        help=f"comma-separated IMU presets ({', '.join(PRESETS)}): shorthand for Zhang 2021's "
        "chain on each, added to --techniques",
    )
    bench.add_argument(
        "--conditions",
        help=f"comma-separated physical-room conditions ({', '.join(CONDITIONS)}; "
        "agents.benchmark.conditions); each a grid axis (main grid: lab)",
    )
    bench.add_argument(
        "--episodes", type=_int_at_least(1), default=DEFAULT_EPISODES, help="episodes per cell"
    )
    bench.add_argument("--seed", type=_int_at_least(0), default=0, help="episode i uses seed + i")
    bench.add_argument(
        "--workers",
        type=_int_at_least(1),
        default=2,
        help="worker processes (--backend ray: the CPUs to cut jobs for)",
    )
    bench.add_argument(
        "--batch-size",
        type=_int_at_least(0),
        default=DEFAULT_BATCH_SIZE,
        help="users stepped together in one vector env (cells sharing a task and technique "
        "mix); 0: every episode alone in a single env (the same results)",
    )
    bench.add_argument(
        "--backend",
        choices=("local", "ray"),
        default="local",
        help="where the episodes run: local worker processes, or Ray tasks on a Ray cluster "
        "(pip install 'vrloco[ray]'; the same results)",
    )
    bench.add_argument(
        "--address",
        help="with --backend ray: the cluster, 'auto' (one started with `ray start` here) or "
        "HOST:PORT of its head; default: such a cluster where one runs, else a local Ray "
        "instance on this machine's cores",
    )
    bench.add_argument("--json", type=_out_file, help="also write the rows to this JSON file")
    bench.add_argument(
        "--out",
        default="out/benchmark",
        type=_out_dir,
        help="folder for CSV, JSON, figures, one run's alone: a folder holding another run's "
        "results (another grid, episode count or seed) is refused, and so is a folder another "
        "run is writing to; the same command again resumes its interrupted run from "
        "OUT/.resume and replaces its own files",
    )
    bench.add_argument(
        "--force",
        action="store_true",
        help="remove another run's results from --out first, then write this run's",
    )
    bench.set_defaults(func=cmd_benchmark)

    techniques = sub.add_parser(
        "techniques", help="list the techniques and every stage's implementations"
    )
    techniques.set_defaults(func=cmd_techniques)

    train = sub.add_parser("train", help="train a PPO user (stable-baselines3 or RLlib) on a task")
    train.add_argument("--task", default="approach", type=_task, help=f"one of {', '.join(TASKS)}")
    train.add_argument(
        "--steps",
        type=_int_at_least(1),
        default=2_000_000,
        help="environment steps, rounded up to whole PPO rollouts (rllib: "
        "whole training iterations)",
    )
    train.add_argument(
        "--num-envs",
        type=_int_at_least(1),
        default=32,
        help="users stepped together (rllib: in each env runner)",
    )
    train.add_argument(
        "--rollout-steps",
        type=_int_at_least(1),
        metavar="N",
        help="each user's steps per PPO rollout (stable-baselines3's n_steps; a rollout is "
        "N x --num-envs steps; default 256; --init keeps the model's own)",
    )
    train.add_argument(
        "--learning-rate",
        type=_positive_float,
        metavar="LR",
        help="PPO's Adam step size (default 3e-4; --init keeps the model's own)",
    )
    train.add_argument(
        "--net-arch",
        type=_layer_sizes,
        metavar="N,N",
        help="hidden layer sizes of the policy's and the value function's networks "
        "(default 64,64, stable-baselines3's; --init keeps the model's own)",
    )
    train.add_argument(
        "--sensors", type=_preset, help="IMU preset (default: the technique's; ig500n)"
    )
    train.add_argument(
        "--technique",
        help="a registered technique (vrloco techniques) or 'module:attr'; several joined "
        "by commas, or 'all' (every registered one), train one user on a mix whose users "
        "share the batch (default: Zhang 2021's chain)",
    )
    train.add_argument(
        "--population",
        help=f"the users' head behaviour in the env: a user population ({', '.join(POPULATIONS)}; "
        "several joined by commas, 'none' among them: a mix; default: none, the head "
        "straight on the torso)",
    )
    train.add_argument(
        "--condition",
        help=f"the physical room's condition ({', '.join(CONDITIONS)}; default: lab)",
    )
    train.add_argument(
        "--frame-stack",
        type=_int_at_least(1),
        default=1,
        metavar="K",
        help="the policy sees each user's last K observations side by side",
    )
    train.add_argument(
        "--recurrent",
        action="store_true",
        help="an LSTM policy (sb3-contrib's RecurrentPPO) instead of PPO's feed-forward one",
    )
    train.add_argument(
        "--reward",
        type=_reward_terms,
        metavar="TERM=W,...",
        help="the training objective's weights over the env's RewardConfig (terms: "
        + ", ".join(f.name for f in dataclasses.fields(RewardConfig))
        + "), e.g. collision=10 or success_without_collision=true; the task and its "
        "measures stay the same",
    )
    train.add_argument(
        "--variability",
        metavar="POPULATION",
        help="train (and evaluate) with a population's human variability around the learner: "
        "reaction delay, turn overshoot, cadence bias and jitter, as the benchmark's "
        "'+POPULATION' users act; with several populations, one per population joined by "
        "commas ('none': none), e.g. --population idealised,typical --variability "
        "none,typical (default: none)",
    )
    train.add_argument(
        "--init",
        metavar="MODEL",
        help="go on training this model (.zip from vrloco train) on this run's cell and "
        "objective, its weights and PPO settings kept (it must see the same frame stack and "
        "observation fields)",
    )
    train.add_argument(
        "--imitate",
        metavar="SCRIPTED_USER",
        help="start from a policy that imitates this scripted user (e.g. goal_seeker; DAgger "
        "on the training users) instead of a random one; one technique (a mix of populations is "
        "fine), no --init or --recurrent",
    )
    train.add_argument(
        "--residual-on",
        metavar="SCRIPTED_USER",
        help="learn a correction of this scripted user's actions (e.g. goal_seeker): the policy "
        "sees its action and adds its own, starting at none (as the scripted user); one "
        "technique, no --imitate, --recurrent or --env-workers",
    )
    train.add_argument(
        "--imitate-steps",
        type=_int_at_least(1),
        metavar="N",
        help="environment steps of the imitation, before PPO's --steps (with --imitate; "
        "default 200,000)",
    )
    train.add_argument(
        "--env-workers",
        type=_int_at_least(1),
        default=1,
        metavar="N",
        help="step the training users in N processes, a share each (the same episodes and "
        "weights for any N; local backend)",
    )
    train.add_argument(
        "--eval-every", type=_int_at_least(1), default=100_000, help="steps between evals"
    )
    train.add_argument(
        "--eval-episodes",
        type=_int_at_least(1),
        default=None,
        metavar="N",
        help="users each evaluation plays (default 32, or one per cell of a mix of more cells)",
    )
    seeding = train.add_mutually_exclusive_group()
    seeding.add_argument("--seed", type=_int_at_least(0), default=0, help="random seed")
    seeding.add_argument(
        "--seeds",
        type=_seed_list,
        metavar="S,S,...",
        help="comma-separated distinct seeds >= 0: one run per seed, each in OUT/seed_<s>/, "
        "in parallel worker processes (one per seed, at most one per core; --backend ray: "
        "Ray tasks; rllib: one after the other), and their curves with the mean and std in "
        "OUT/learning_curve.json and .png (default: one run, --seed)",
    )
    train.add_argument(
        "--backend",
        choices=("local", "ray", "rllib"),
        default="local",
        help="local: stable-baselines3 PPO, several seeds in local worker processes; ray: "
        "the same, each seed a Ray task on a Ray cluster (pip install 'vrloco[ray]'); rllib: "
        "RLlib's PPO on --env-runners env runners of --num-envs users each, seeds one after "
        "the other (pip install 'vrloco[rllib]')",
    )
    train.add_argument(
        "--address",
        help="with --backend ray or rllib: the cluster, 'auto' (one started with `ray start` "
        "here) or HOST:PORT of its head; default: such a cluster where one runs, else a local "
        "Ray instance on this machine's cores",
    )
    train.add_argument(
        "--env-runners",
        type=_int_at_least(0),
        default=None,
        help="with --backend rllib: RLlib env runners (processes sampling in parallel; 0: "
        "sample in this process) (default: 2)",
    )
    train.add_argument(
        "--out", default="runs/ppo", type=_out_dir, help="folder for logs and models"
    )
    train.set_defaults(func=cmd_train)

    evaluate = sub.add_parser(
        "evaluate",
        help="the benchmark's metrics for a trained PPO model",
        description="Plays the model's seeded episodes (a progress bar) and prints the "
        "benchmark's table for its row; --json writes the row (every metric) as the benchmark's "
        "JSON does.",
    )
    evaluate.add_argument("model", help="path of a saved PPO model (.zip)")
    evaluate.add_argument(
        "--task", help=f"one of {', '.join(TASKS)} (default: the task the model was trained on)"
    )
    evaluate.add_argument("--episodes", type=_int_at_least(1), default=100, help="seeded episodes")
    evaluate.add_argument("--sensors", type=_preset, help="IMU preset (default: the model's own)")
    for name in ("technique", "population", "condition"):
        evaluate.add_argument(f"--{name}", help=f"the {name} (default: the model's own)")
    evaluate.add_argument(
        "--allow-mismatch",
        action="store_true",
        help="evaluate on a task, technique, population, condition or sensors "
        "other than the model's (else an error naming what differs)",
    )
    evaluate.add_argument("--seed", type=_int_at_least(0), default=0, help="random seed")
    evaluate.add_argument(
        "--json", type=_out_file, help="also write the row (every metric) to this JSON file"
    )
    evaluate.set_defaults(func=cmd_evaluate)
    rec = sub.add_parser(
        "record",
        help="an offline-RL dataset: a policy's seeded episodes as a Minari dataset",
        description="Plays --episodes seeded episodes of --policy as the benchmark plays them "
        "(episode i: seed + i) on gym.make('VRLoco-<Task>-v0', technique=..., population=...) "
        "and writes them as the Minari dataset --minari (observations, actions, rewards, "
        "terminations, truncations, the infos the benchmark's metrics read, each episode's "
        "seed) in $MINARI_DATASETS_PATH, else ~/.minari/datasets; its recover_environment() "
        "makes the same env (pip install 'vrloco[minari]').",
    )
    rec.add_argument("--task", required=True, type=_task, help=f"one of {', '.join(TASKS)}")
    rec.add_argument(
        "--policy",
        required=True,
        help="goal_seeker, avoid_manoeuvre, reactive_avoider, a stable-baselines3 model (.zip) "
        f"or 'module:attr'; append +<population> ({', '.join(POPULATIONS)}) for a human "
        "population",
    )
    rec.add_argument(
        "--technique",
        default="zhang2021",
        help="a technique (vrloco techniques lists them) or 'module:attr'",
    )
    rec.add_argument("--episodes", type=_int_at_least(1), default=100, help="seeded episodes")
    rec.add_argument("--seed", type=_int_at_least(0), default=0, help="episode i uses seed + i")
    rec.add_argument(
        "--max-episode-steps",
        type=_int_at_least(1),
        help="the env's horizon in control steps (default: the env's own)",
    )
    rec.add_argument(
        "--minari",
        required=True,
        metavar="DATASET_ID",
        help="the dataset's id, (namespace/)name-v<version>",
    )
    rec.add_argument(
        "--force",
        action="store_true",
        help="replace an existing dataset of that id (once the episodes are played)",
    )
    rec.set_defaults(func=cmd_record)
    est = sub.add_parser(
        "estimate",
        help="attitude, steps and the eq (17) path of a recording (CSV, BROAD or Oxford)",
        description=(
            "CSV columns: t (s), gx gy gz (rad/s), ax ay az (m/s^2), optional mx my mz "
            "(any fixed unit); t, the gyro and the accelerometer in other units are found from "
            "the data or given with --time-unit, --gyro-unit, --acc-unit (a unit read other "
            "than these is said in one line). Also reads BROAD .hdf5/.mat trials and Oxford "
            "step-counter folders. Writes NAME_estimates.csv and NAME_estimates.png."
        ),
    )
    est.add_argument("path", help="a CSV file, a BROAD trial or an Oxford folder")
    est.add_argument("--out", default="out", type=_out_dir, help="output folder")
    est.add_argument("--step-length", type=float, default=0.7, help="eq (17) SL in m")
    est.add_argument(
        "--offline", action="store_true", help="attitude from the forward-backward smoother"
    )
    est.add_argument(
        "--time-unit",
        choices=("auto", "s", "ms", "us", "ns"),
        default="auto",
        help="unit of a CSV's t; auto: the one in which the median interval is 5 Hz to 10 kHz "
        "(an error where none or two are)",
    )
    est.add_argument(
        "--acc-unit",
        choices=("auto", "m/s2", "g"),
        default="auto",
        help="unit of a CSV's ax ay az; auto: the one in which the median norm of the 1 s "
        "means is 0.5 g to 2 g (gravity; an error where neither is)",
    )
    est.add_argument(
        "--gyro-unit",
        choices=("auto", "rad/s", "deg/s"),
        default="auto",
        help="unit of a CSV's gx gy gz. auto, in order: deg/s where at least 10 samples and "
        "1%% exceed 35 rad/s (2000 deg/s); else the magnetometer's verdict (its field turns "
        "0.5-2 times (rad/s) or 35-95 times (deg/s) slower than the gyro's numbers say); else "
        "the accelerometer's (gravity, carried by the gyro through 4 s windows, spreads at "
        "least 2 times and 2 deg less in one unit than in the other); with no verdict, rad/s "
        "where the gyro read as rad/s turns the sensor under 10 deg in every 4 s window, else "
        "an error asking for this option. Evidence against the unit read is a one-line warning",
    )
    est.set_defaults(func=cmd_estimate)
    dat = sub.add_parser(
        "data",
        help="the real recordings: list them, fetch them into the cache, say where they are",
        description=(
            "Real recordings are found in $VRLOCO_DATA (a folder laid out as broad/, "
            "oxford_steps/, kinect_laban/, head_traces/), else in the download cache "
            "($VRLOCO_CACHE, default ~/.cache/vrloco). `fetch` downloads broad, oxford or kinect "
            "from its canonical source (or $VRLOCO_DATA_URL) and checks each file's pinned "
            "SHA-256; head_traces cannot be fetched (no licence is stated) and is found only in "
            "$VRLOCO_DATA."
        ),
    )
    dat_sub = dat.add_subparsers(dest="data_command", metavar="ACTION", required=True)
    dat_sub.add_parser("list", help="each set: where it is found, its size and licence")
    where = dat_sub.add_parser(
        "where", help="the path the readers take for NAME (without NAME: the cache folder)"
    )
    where.add_argument("name", nargs="?", help="a set (broad, oxford, kinect, head_traces)")
    fetch = dat_sub.add_parser("fetch", help="download sets into the cache, checking each hash")
    fetch.add_argument("names", nargs="+", metavar="NAME", help="broad, oxford or kinect")
    fetch.add_argument(
        "--url",
        help="download BASE/RELPATH from this base URL instead of the "
        "canonical sources (default: $VRLOCO_DATA_URL)",
    )
    dat.set_defaults(func=cmd_data)
    return parser
