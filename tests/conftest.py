"""Shared fixtures. Tests that need real data skip with a clear message when HYPERLF_DATA is unset."""

from __future__ import annotations

import numpy as np
import pytest

from hyperlf.datasets import ENV_VAR, has_data, dataset_path


def require_dataset(name: str):
    """Return the dataset's path or skip the test, saying how to enable it."""
    if not has_data(name):
        pytest.skip(f"needs the real data: set {ENV_VAR} to the shared data folder ({name})")
    return dataset_path(name)


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
