"""The noise floor's per-row filter gain (kukaid.diagnose.noise.row_noise_gain) of a log shorter than
the gain's kernel (2049 samples: 8 s of a run-admittance log at 12 ms) is read at the right rows."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from kukaid.diagnose.noise import row_noise_gain
from kukaid.identify.filtering import lowpass


def _sig(n: int, weight=None):
    filt = lambda x: lowpass(x, 83.33, 5.0, 3)[0]  # noqa: E731  the comparison filter of a KR C4 log
    return SimpleNamespace(n=n, weight=weight, rows=np.arange(100, n - 100), filt=filt)


@pytest.mark.parametrize("n", [400, 700, 1875, 2049, 5000])
def test_the_gain_inside_a_log_of_moving_samples_is_the_filters_white_noise_gain(n):
    imp = np.zeros(2049)
    imp[1024] = 1.0
    full = float(np.sum(lowpass(imp, 83.33, 5.0, 3)[0] ** 2))
    g = row_noise_gain(_sig(n))
    # before: a 700-sample log got gains near 0 (the diagnosis printed 7.4e17 x the noise floor)
    assert g == pytest.approx(full, rel=1e-6)


def test_standstill_rows_lower_the_gain_where_they_are():
    n = 700
    w = np.ones(n)
    w[300:400] = 0.0
    g = row_noise_gain(_sig(n, w))
    rows = np.arange(100, n - 100)
    assert g[rows == 350][0] < 0.05 * g[rows == 150][0]  # in the standstill, not 87 or 674 rows away
    assert g[rows == 150][0] == pytest.approx(g[rows == 550][0], rel=1e-6)
