"""The command line refuses bad options with one clear line, before any work starts."""

import pytest

from agents.cli import main
from agents.learned.train import rollout_steps


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["train", "--task", "nope"], "task='nope': unknown; valid names: approach"),
        (["train", "--num-envs", "0"], "--num-envs: 0 must be >= 1"),
        (["train", "--steps", "0"], "--steps: 0 must be >= 1"),
        (["train", "--sensors", "nope"], "--sensors"),
        (["train", "--seeds", "1,1"], "--seeds: seed 1 is given twice"),
        (["train", "--seeds", "x"], "--seeds: 'x' is not an integer"),
        (["train", "--seeds", "0,-1"], "--seeds: -1 must be >= 0"),
        (["train", "--seeds", "0,1", "--seed", "2"], "not allowed with argument --seeds"),
        (["evaluate", "--episodes", "0", "m.zip"], "--episodes: 0 must be >= 1"),
        (["demo", "--sensors", "nope"], "--sensors"),
        (["experiment", "head-motions", "--users", "0"], "--users: 0 must be >= 1"),
        (["benchmark", "--out", "/proc/nope"], "cannot write to '/proc/nope'"),
        (["benchmark", "--episodes", "two"], "'two' is not an integer"),
    ],
)
def test_bad_options_get_one_clear_line(argv, message, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_outputs_are_checked_before_the_work(tmp_path, capsys):
    taken = tmp_path / "file.txt"
    taken.write_text("x")
    with pytest.raises(SystemExit):
        main(["estimate", str(taken), "--out", str(taken)])
    assert "is a file, not a folder" in capsys.readouterr().err
    assert main(["estimate", str(tmp_path), "--out", str(tmp_path / "o")]) == 2
    assert "not an Oxford step-counter recording" in capsys.readouterr().err


def test_help_shows_the_defaults(capsys):
    with pytest.raises(SystemExit):
        main(["train", "--help"])
    out = capsys.readouterr().out
    assert "(default: 2000000)" in out and "(default: approach)" in out
    from agents.benchmark.episodes import DEFAULT_BATCH_SIZE
    from agents.benchmark.grid import DEFAULT_EPISODES

    with pytest.raises(SystemExit):
        main(["benchmark", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert f"episodes per cell (default: {DEFAULT_EPISODES})" in out
    assert f"(the same results) (default: {DEFAULT_BATCH_SIZE})" in out


def test_training_steps_are_whole_rollouts(capsys):
    assert rollout_steps(8192, 256, 32) == 8192
    assert rollout_steps(10_000, 256, 32) == 16_384
    assert "rounded up" in capsys.readouterr().out
    with pytest.raises(ValueError, match="rollouts of n_steps x num_envs = 256 x 32 = 8,192"):
        rollout_steps(1000, 256, 32)


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--imitate-steps", "1000"], "--imitate-steps needs --imitate SCRIPTED_USER"),
        (["--imitate", "nobody"], "not a scripted user; choose from"),
        (["--imitate", "goal_seeker", "--recurrent"], "a feed-forward policy"),
    ],
)
def test_an_imitation_train_cannot_run_is_refused_before_the_work(argv, message, tmp_path, capsys):
    code = main(["train", "--task", "approach", "--out", str(tmp_path / "run"), *argv])
    assert code == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert not (tmp_path / "run" / "imitation.json").exists()
