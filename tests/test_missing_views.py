"""Views that cannot see a sample (issue 11, item 3): averaging over the views that do see it
pulls textureless pixels to the range limits, where fewer, noisier costs are averaged;
``missing_views="neutral"`` removes that bias."""

from __future__ import annotations

import numpy as np
import pytest

from hyperlf import hlf
from hyperlf.errors import InvalidInputError
from hyperlf.lightfield import LightField


def at_limits(mode: str) -> float:
    """Fraction of pixels at a range limit on a textureless scene (flat grey + noise): with no
    information every label is as likely, so 2 of 17 labels = 11.8 % is the unbiased answer."""
    rng = np.random.default_rng(0)
    views = 0.5 + 0.01 * rng.standard_normal((3, 3, 40, 48)).astype(np.float32)
    lf = LightField(views=views, disparity_range=(-8.0, 8.0))
    params = hlf.DepthParams(missing_views=mode, median_radius=0)
    d = hlf.depth(lf, n_labels=17, metric="ncc", optimizer="wta", params=params).disparity
    return float(np.mean(np.abs(np.abs(d) - 8.0) < 1e-3))


def test_neutral_missing_views_remove_the_pull_to_the_range_limits():
    unbiased = 2 / 17
    average, neutral = at_limits("average"), at_limits("neutral")
    assert abs(neutral - unbiased) < 0.025, neutral
    assert average > neutral + 0.03, (average, neutral)


def test_neutral_keeps_labels_every_view_sees():
    C = np.array([[[1.0]], [[2.0]], [[3.0]]], np.float32)
    n = np.array([[[4]], [[4]], [[2]]])
    out = hlf.neutral_missing_views(C, n)
    np.testing.assert_allclose(out[:2, 0, 0], [1.0, 2.0])
    np.testing.assert_allclose(out[2, 0, 0], (3.0 * 2 + 2 * 2.0) / 4)  # median 2.0 fills in
    assert np.isnan(hlf.neutral_missing_views(C, np.zeros_like(n))).all()


def test_missing_views_option_is_checked():
    with pytest.raises(InvalidInputError, match="missing_views"):
        hlf.DepthParams(missing_views="ignore")
