"""``python -m agents.experiments.hand_variance [--only yao2023 adaptive_kalman one_euro]``: the
tuning rules on the development seeds (:func:`agents.experiments.hand_variance.tuning.run_tuning`).
"""

import argparse

from agents.experiments.hand_variance.tuning import run_tuning

if __name__ == "__main__":
    parser = argparse.ArgumentParser(
        prog="python -m agents.experiments.hand_variance",
        description="tune the hand filters on the development seeds",
    )
    parser.add_argument(
        "--only",
        nargs="+",
        default=["yao2023", "adaptive_kalman", "one_euro"],
        choices=["yao2023", "adaptive_kalman", "one_euro"],
    )
    run_tuning(tuple(parser.parse_args().only))
