"""Shared helpers of the six-axis tests: the robot under test and a smooth all-axis trajectory."""
from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from shared_data import SHARED

ROOT = Path(__file__).resolve().parents[1]
_BUNDLED = ROOT / "kukaid" / "robots" / "kr6_r700_sixx.urdf"
_LWR4 = SHARED / "datasets" / "lwr4" / "kuka_lwr4.urdf"

if _BUNDLED.is_file():
    ROBOT = "kr6-r700-sixx"
elif _LWR4.is_file():
    ROBOT = str(_LWR4)
else:  # pragma: no cover
    pytest.skip("no robot URDF (bundled KR 6 R700 sixx or ../shared LWR4)", allow_module_level=True)


def fourier_like(n: int, duration: float, amp: float = 0.4, dt: float = 0.012) -> SimpleNamespace:
    """A smooth all-axis trajectory starting and ending at rest (raised-cosine window)."""
    t = np.arange(0.0, duration + 1e-9, dt)
    w = np.sin(np.pi * t / duration) ** 2
    q = np.stack([amp * w * np.sin(2 * np.pi * t * (0.4 + 0.13 * i)) for i in range(n)], axis=1)
    return SimpleNamespace(t=t, q=q, axes=tuple(range(1, n + 1)), kind="custom", params={})
