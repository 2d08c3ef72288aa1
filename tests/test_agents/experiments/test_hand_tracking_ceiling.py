"""The hand tasks' split by tracking: a user turned away from the Kinect at the pedestal is
followed by an estimate that is not its hand, and the hold fails."""

import numpy as np

from agents.experiments.hand_tracking_ceiling import hand_tracking_split


def test_reach_episodes_split_into_tracked_successes_and_mistracked_failures():
    r = hand_tracking_split("reach", episodes=6, seed=1000)
    medians = np.asarray(r["median_error_deg"])
    assert r["at_goal"] == 6 and np.isfinite(medians).all()
    flipped = medians > 90.0
    assert r["mistracked"] == flipped.sum() >= 1  # seed 1005 stands with its back to the sensor
    assert (medians[~flipped] < 20.0).all() and (medians[flipped] > 150.0).all()  # no middle
    assert r["success_tracked"] == (~flipped).sum()  # every tracked hold succeeds here
    assert r["success"] == r["success_tracked"] + r["success_mistracked"]
    assert 0 <= r["recovered"] <= r["mistracked"]
    assert r["turned_mistracked_deg"] >= 0.0
    assert r["nearest_m"] == [0.0] * 6 and r["short"] == 0  # all stood in the goal region
