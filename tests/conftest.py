"""Shared fixtures: a seeded generator, and the real recordings as :mod:`agents.recordings.data`
finds them (``$VRLOCO_DATA``, which the test session points at ../shared/data beside the repository
unless it is set, else the download cache)."""

import os
from pathlib import Path

import numpy as np
import pytest

from agents.recordings.data import DataMissing, data_path

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
os.environ.setdefault("VRLOCO_DATA", str(SHARED_DATA))


@pytest.fixture
def rng():
    return np.random.default_rng(20261123)


@pytest.fixture
def real_data():
    """``real_data(name)``: :func:`agents.recordings.data.data_path` of a set of real recordings; a
    test that needs an absent set skips, saying how to fetch it."""

    def find(name: str) -> Path:
        try:
            return data_path(name)
        except DataMissing as err:
            pytest.skip(f"real recordings: {err}")

    return find
