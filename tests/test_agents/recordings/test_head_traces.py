"""The head-trace reader: the layout, one clear error per malformed file, the datasets."""

from pathlib import Path

import numpy as np
import pytest

from agents.recordings.head_traces import (
    DATASETS,
    data_folder,
    dataset_files,
    dataset_of,
    head_traces_folder,
    read_head_traces,
)

TIMES = " ".join(f"{k / 10:g}" for k in range(5))


def write(tmp_path: Path, text: str, name: str = "3.txt") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_viewings_of_different_lengths_are_cut_to_their_own_length(tmp_path):
    path = write(
        tmp_path, f"{TIMES}\n0.1 0.2 0.3 0.4 0.5\n3.1 -3.1 3.0 2.9 2.8\n-0.1 -0.2 -0.3\n1 2 3\n\n"
    )
    f = read_head_traces(path)
    np.testing.assert_allclose(f.times, [0.0, 0.1, 0.2, 0.3, 0.4])
    assert f.pitch.shape == f.yaw.shape == (2, 5) and f.lengths.tolist() == [5, 3]
    assert np.isnan(f.pitch[1, 3:]).all()
    (t0, p0, y0), (t1, p1, y1) = f.viewings()
    np.testing.assert_allclose(t0, f.times)
    np.testing.assert_allclose(p0, [0.1, 0.2, 0.3, 0.4, 0.5])
    np.testing.assert_allclose(y0, [3.1, -3.1, 3.0, 2.9, 2.8])
    np.testing.assert_allclose(y1, [1.0, 2.0, 3.0])
    np.testing.assert_allclose(t1, [0.0, 0.1, 0.2])
    np.testing.assert_allclose(p1, [-0.1, -0.2, -0.3])
    assert f.dataset == "corbillon2017" and f.pitch_line(1) == 4


@pytest.mark.parametrize(
    ("text", "match"),
    [
        (f"{TIMES}\n0 0 zero 0 0\n0 0 0 0 0\n", r"3.txt:2: value 3 'zero' is not a number"),
        (f"{TIMES}\n0 0 0 0 0\n0 0 nan 0 0\n", r"3.txt:3: value 3 is nan: .* finite"),
        (f"{TIMES}\n0 0 0 0 0\n0 0 0 0\n", r"3.txt:3: 4 yaw values after 5 pitch values"),
        (f"{TIMES}\n0 0 0 0 0\n0 0 0 0 0\n0 0 0 0 0\n", r"3.txt:4: 4 lines: .* must be odd"),
        (f"{TIMES}\n0 0 0 0 0 0\n0 0 0 0 0 0\n", r"3.txt:2: 6 values, more than the 5 sample"),
        ("0 0.1 0.1 0.3\n0 0 0 0\n0 0 0 0\n", r"3.txt:1: the times must increase strictly"),
        (f"{TIMES}\n", r"3.txt:1: 1 line\(s\)"),
        (f"{TIMES}\n0\n0\n", r"3.txt:2: 1 value\(s\): a viewing needs at least two samples"),
        (f"{TIMES}\n\n0 0 0 0 0\n", r"3.txt:2: empty line"),
    ],
)
def test_a_malformed_file_is_one_error_naming_the_file_and_line(tmp_path, text, match):
    with pytest.raises(ValueError, match=match):
        read_head_traces(write(tmp_path, text))


def test_missing_files_and_folders_and_unknown_names_are_named(tmp_path, monkeypatch):
    with pytest.raises(FileNotFoundError, match="no such head-trace file"):
        read_head_traces(tmp_path / "0.txt")
    monkeypatch.setenv("VRLOCO_DATA", str(tmp_path))
    assert data_folder() == tmp_path
    with pytest.raises(
        FileNotFoundError,
        match=r"head traces not found at .*head_traces'.* "
        r"VRLOCO_DATA",
    ):
        head_traces_folder()
    with pytest.raises(FileNotFoundError, match=r"head traces not found .* VRLOCO_DATA"):
        dataset_files()
    with pytest.raises(ValueError, match=r"'20.txt': not a head-trace file of a known dataset"):
        dataset_of("20.txt")
    with pytest.raises(ValueError, match=r"'38\.txt'"):  # Wu et al.'s video 38 is not in the set
        dataset_of("38.txt")
    assert dataset_of(Path("x") / "41.txt") == "wu2017"


def test_the_real_folder_holds_the_three_datasets(real_data):
    folder = real_data("head_traces")
    files = dataset_files(folder)
    assert {k: len(v) for k, v in files.items()} == {"corbillon2017": 7, "lo2017": 10, "wu2017": 8}
    for name, paths in files.items():
        assert all(dataset_of(p) == name for p in paths)
        assert [int(p.stem) for p in paths] == [n for n in DATASETS[name][1]]
    f = read_head_traces(folder / "7.txt")  # Lo et al.: 60 s viewings at 10 Hz
    assert f.times.size == 600 and f.pitch.shape == (50, 600)
    np.testing.assert_allclose(np.diff(f.times), 0.1, atol=1e-9)
    assert (f.lengths == 600).all() and np.isfinite(f.yaw).all()
    assert np.abs(f.yaw).max() <= np.pi + 1e-9  # wrapped at +-pi
