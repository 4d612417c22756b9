"""The one helper for distance travelled along a track."""

from __future__ import annotations

import math

import numpy as np

from autosar_cli.nav.trajectory import cumulative_travel


def test_cumulative_travel_sums_the_steps() -> None:
    rng = np.random.default_rng(3)
    for dims in (2, 3):
        points = rng.normal(size=(50, dims)) * 4.0
        expected = [0.0]
        for a, b in zip(points[:-1], points[1:], strict=True):
            step = math.sqrt(sum((float(x) - float(y)) ** 2 for x, y in zip(a, b, strict=True)))
            expected.append(expected[-1] + step)
        np.testing.assert_allclose(cumulative_travel(points), expected, rtol=1e-14, atol=1e-12)
    # a 3-4-5 step, a standstill, then back: travel counts every metre
    assert cumulative_travel([[0, 0], [3, 4], [3, 4], [0, 0]]).tolist() == [0.0, 5.0, 5.0, 10.0]
    assert cumulative_travel(np.zeros((1, 2))).tolist() == [0.0]
