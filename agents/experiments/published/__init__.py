"""Published user-study findings reproduced on the testbed: the scenarios, written down before
they were run on the reporting seeds (:mod:`~agents.experiments.published.scenarios`), and their
runner (:mod:`~agents.experiments.published.run`, ``vrloco experiment published``)."""

from agents.experiments.published.run import decide, run_published
from agents.experiments.published.scenarios import ALPHA, DEV_SEEDS, FINDINGS, REPORT_SEEDS, Finding

__all__ = ["ALPHA", "DEV_SEEDS", "FINDINGS", "REPORT_SEEDS", "Finding", "decide", "run_published"]
