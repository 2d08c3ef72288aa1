"""Same seed, same episode, bit for bit: every recorded case replays exactly, except the cases
that run OpenCV's pose solver, whose rounding follows the OpenCV release and the host CPU's SIMD
path: they replay bit for bit within one machine and within :data:`OPENCV_ATOL` of the recording."""

import cv2
import numpy as np
import pytest
from golden_episodes import GOLDEN, OPENCV_ATOL, OPENCV_CASES, OPENCV_KEY, cases

CASES = cases()


@pytest.fixture(scope="module")
def recorded():
    if not GOLDEN.exists():
        pytest.fail(f"{GOLDEN} is missing: record it with `python tests/golden_episodes.py`")
    with np.load(GOLDEN) as data:
        return {name: data[name] for name in data.files}


def test_every_case_is_recorded(recorded):
    assert sorted(k for k in recorded if k != OPENCV_KEY) == sorted(CASES)


@pytest.mark.parametrize("name", sorted(CASES))
def test_case_replays_bit_for_bit(name, recorded):
    got = CASES[name]()
    want = recorded[name]
    assert got.shape == want.shape, f"{name}: {got.size} numbers, recorded {want.size}"
    if name in OPENCV_CASES:
        again = CASES[name]()
        np.testing.assert_array_equal(
            got.view(np.uint64),
            again.view(np.uint64),
            err_msg=f"{name}: two replays on this machine differ",
        )
        np.testing.assert_allclose(
            got,
            want,
            rtol=0.0,
            atol=OPENCV_ATOL,
            err_msg=(
                f"{name}: recorded under OpenCV {recorded.get(OPENCV_KEY, 'unknown')}, replayed "
                f"under {cv2.__version__} on this CPU"
            ),
        )
        return
    differ = np.flatnonzero(got.view(np.uint64) != want.view(np.uint64))
    assert differ.size == 0, (
        f"{name}: {differ.size} of {got.size} numbers differ, first at {differ[0]}: "
        f"{got[differ[0]]!r} vs recorded {want[differ[0]]!r}"
    )
