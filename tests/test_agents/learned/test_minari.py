"""``vrloco record``: a policy's seeded episodes as a Minari dataset, read back bit for bit, with
the env that ``recover_environment`` makes and the benchmark's metrics of the stored episodes.

Every dataset lands in a temporary ``MINARI_DATASETS_PATH``, never in the user's home.
"""

import math

import gymnasium as gym
import numpy as np
import pytest

import vrloco_env  # noqa: F401  (registers the ids)
from agents.benchmark.episodes import run_episode
from agents.benchmark.metrics import STEP_KEYS, TRACE_KEYS, summarize
from agents.benchmark.policies import build_policy
from agents.cli import main
from agents.learned.offline_datasets import LAST_KEYS, dataset_episode_stats, record_dataset

TASK, POLICY, TECHNIQUE = "avoid", "goal_seeker+typical", "nod_robust"
ENV_ID, POPULATION = "VRLoco-Avoid-v0", "typical"
SEED, EPISODES, HORIZON = 7, 2, 30
DATASET = "vrloco/test-avoid-v0"


def _make_env() -> gym.Env:
    return gym.make(ENV_ID, technique=TECHNIQUE, population=POPULATION, max_episode_steps=HORIZON)


def _play(seed: int) -> dict:
    """One episode played here, independently of the recorder: the policy as the benchmark
    builds it, its randomness from default_rng([seed, 1])."""
    env = _make_env()
    policy = build_policy(POLICY, env)
    obs, reset_info = env.reset(seed=seed)
    policy.reset(np.random.default_rng([seed, 1]))
    ep = {
        "observations": [obs],
        "actions": [],
        "rewards": [],
        "terminations": [],
        "truncations": [],
        "infos": [],
        "reset_info": reset_info,
    }
    while True:
        action = np.asarray(policy.act(obs))
        obs, reward, terminated, truncated, info = env.step(action)
        for key, value in (
            ("observations", obs),
            ("actions", action),
            ("rewards", reward),
            ("terminations", terminated),
            ("truncations", truncated),
            ("infos", info),
        ):
            ep[key].append(
                {k: np.array(v) for k, v in info.items()} if key == "infos" else np.array(value)
            )  # copies: an env may reuse its buffers
        if terminated or truncated:
            break
    env.close()
    return {k: (v if k in ("infos", "reset_info") else np.asarray(v)) for k, v in ep.items()}


@pytest.fixture(scope="module")
def minari_root(tmp_path_factory):
    with pytest.MonkeyPatch.context() as mp:
        root = tmp_path_factory.mktemp("minari")
        mp.setenv("MINARI_DATASETS_PATH", str(root))
        yield root


@pytest.fixture(scope="module")
def recorded(minari_root):
    import minari

    record_dataset(
        TASK,
        POLICY,
        DATASET,
        technique=TECHNIQUE,
        episodes=EPISODES,
        seed=SEED,
        max_episode_steps=HORIZON,
    )
    return minari.load_dataset(DATASET)


@pytest.fixture(scope="module")
def played():
    return [_play(SEED + i) for i in range(EPISODES)]


def test_loaded_episodes_equal_the_played_ones(recorded, played, minari_root):
    assert (minari_root / DATASET / "data").is_dir()
    assert recorded.total_episodes == EPISODES
    meta = list(recorded.storage.get_episode_metadata(recorded.episode_indices))
    assert [m["seed"] for m in meta] == [SEED + i for i in range(EPISODES)]
    for ep, want in zip(recorded.iterate_episodes(), played, strict=True):
        for key in ("observations", "actions", "rewards", "terminations", "truncations"):
            np.testing.assert_array_equal(getattr(ep, key), want[key], err_msg=key, strict=True)
        assert ep.terminations[-1] or ep.truncations[-1]
        assert len(ep) == len(want["rewards"]) <= HORIZON
        # infos: one row for the reset, then one per step; every key the metrics read
        needed = {*STEP_KEYS, *TRACE_KEYS, *LAST_KEYS, "shortest_path", "position"}
        assert needed <= set(ep.infos)
        for key in needed:
            rows = ep.infos[key]
            assert rows.shape[0] == len(ep) + 1, key
            steps = np.stack([np.asarray(info[key]) for info in want["infos"]])
            np.testing.assert_array_equal(rows[1:], steps, err_msg=key, strict=True)
        for key in ("shortest_path", "position", "is_success", "collisions"):
            np.testing.assert_array_equal(ep.infos[key][0], want["reset_info"][key])
        assert np.isnan(ep.infos["attitude_error_deg"][0])  # the reset reports none


def test_recover_environment_makes_the_same_env(recorded):
    original = _make_env()
    env = recorded.recover_environment()
    assert env.spec.id == original.spec.id == ENV_ID
    assert (
        env.spec.kwargs
        == original.spec.kwargs
        == {"task": TASK, "technique": TECHNIQUE, "population": POPULATION}
    )
    assert env.spec.max_episode_steps == HORIZON
    assert env.unwrapped.config == original.unwrapped.config
    meta = list(recorded.storage.get_episode_metadata(recorded.episode_indices))
    for ep, m in zip(recorded.iterate_episodes(), meta, strict=True):
        obs, _ = env.reset(seed=m["seed"])
        np.testing.assert_array_equal(obs, ep.observations[0], strict=True)
        for t, action in enumerate(ep.actions):
            obs, reward, terminated, truncated, _ = env.step(action)
            np.testing.assert_array_equal(obs, ep.observations[t + 1], strict=True)
            assert (reward, terminated, truncated) == (
                ep.rewards[t],
                ep.terminations[t],
                ep.truncations[t],
            )
    env.close()
    original.close()


def test_benchmark_metrics_from_the_stored_episodes(recorded):
    env = _make_env()
    policy = build_policy(POLICY, env)
    want = [run_episode(env, policy, SEED + i, name=POLICY)[0] for i in range(EPISODES)]
    env.close()
    got = dataset_episode_stats(recorded)
    assert [e.seed for e in got] == [e.seed for e in want] == [SEED, SEED + 1]
    for g, w in zip(got, want, strict=True):
        assert (g.success, g.collisions, g.steps, g.elapsed_s, g.walked_m, g.shortest_m) == (
            w.success,
            w.collisions,
            w.steps,
            w.elapsed_s,
            w.walked_m,
            w.shortest_m,
        )
        np.testing.assert_array_equal(g.attitude_error_deg, w.attitude_error_deg)
        np.testing.assert_array_equal(g.true_step_times, w.true_step_times)
        assert g.motion.keys() == w.motion.keys()
    row_got, row_want = summarize(got), summarize(want)
    assert row_got.keys() == row_want.keys()
    for key, value in row_want.items():
        if isinstance(value, float) and math.isnan(value):
            assert math.isnan(row_got[key]), key
        else:
            assert row_got[key] == value, key
    assert math.isfinite(row_got["attitude_rmse_deg"]) and row_got["attitude_rmse_deg"] > 0


def test_an_existing_dataset_is_refused_unless_forced(minari_root, capsys):
    import minari

    name = "vrloco/forced-v0"
    argv = [
        "record",
        "--task",
        "approach",
        "--policy",
        "goal_seeker",
        "--episodes",
        "1",
        "--max-episode-steps",
        "8",
        "--minari",
        name,
    ]
    assert main(argv) == 0
    capsys.readouterr()
    assert minari.load_dataset(name).total_steps == 8
    argv[argv.index("8")] = "5"
    assert main(argv) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert name in err and str(minari_root / name) in err and "--force" in err
    assert minari.load_dataset(name).total_steps == 8  # left as it was
    with pytest.raises(FileExistsError, match="already exists"):
        record_dataset("approach", "goal_seeker", name, episodes=1, max_episode_steps=5)
    assert main([*argv, "--force"]) == 0
    assert minari.load_dataset(name).total_steps == 5
    # a namespace holding other datasets is never removed, --force or not
    (minari_root / "vrloco" / "nested-v0").mkdir()
    (minari_root / "vrloco" / "nested-v0" / "other-v0").mkdir()
    with pytest.raises(FileExistsError, match="not removed"):
        record_dataset(
            "approach",
            "goal_seeker",
            "vrloco/nested-v0",
            episodes=1,
            max_episode_steps=5,
            force=True,
        )
    assert (minari_root / "vrloco" / "nested-v0" / "other-v0").is_dir()


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--policy", "goal_seker"], "policy='goal_seker': unknown; valid names: goal_seeker"),
        (["--policy", "goal_seeker+nope"], "unknown population 'nope'"),
        (["--technique", "nope"], "technique='nope': unknown; valid names: zhang2021"),
        (["--minari", "no_version"], "minari dataset id 'no_version': must be"),
        (["--minari", "../up-v0"], "minari dataset id '../up-v0': must be"),
    ],
)
def test_bad_input_gets_one_line(options, message, minari_root, capsys):
    argv = [
        "record",
        "--task",
        "approach",
        "--policy",
        "goal_seeker",
        "--technique",
        "zhang2021",
        "--minari",
        "bad/x-v0",
    ]
    for flag, value in zip(options[::2], options[1::2], strict=True):
        argv[argv.index(flag) + 1] = value
    before = sorted(minari_root.rglob("*"))
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err and "Traceback" not in err
    assert sorted(minari_root.rglob("*")) == before  # nothing written


def test_an_unknown_task_is_refused_by_the_parser(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["record", "--task", "nope", "--policy", "goal_seeker", "--minari", "x-v0"])
    assert exit_.value.code == 2
    assert "task='nope': unknown; valid names: approach" in capsys.readouterr().err


def test_without_minari_one_line_says_how_to_install(monkeypatch, minari_root, capsys):
    import sys

    monkeypatch.setitem(sys.modules, "minari", None)  # `import minari` raises ImportError
    argv = ["record", "--task", "approach", "--policy", "goal_seeker", "--minari", "y-v0"]
    assert main(argv) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "Minari is not installed" in err and "pip install 'vrloco[minari]'" in err
