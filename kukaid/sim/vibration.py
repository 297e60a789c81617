"""Ambient vibration from axis 6: micro-motion of A3 while it stands (paper, section 3.4).

In the paper A6 moves at random while A3 is held; A3's motor torque then traces Maxwell-slip
hysteresis loops against its position.  What reaches A3 is the elastic deflection of the arm that
A6's reactions cause, seen by the A3 servo as a small disturbance of its position reference: the
servo pushes the joint back and forth by 1e-5 to 1e-4 rad against its pre-sliding friction, and the
motor torque it needs is the friction torque (plus gravity), which is the paper's eq. (11).

We model the deflection ``x`` as band-limited Gaussian noise: white noise through the resonant
second-order filter ``x'' + 2 zeta w x' + w^2 x = G n(t)``, ``w = 2 pi vib_freq``, with the gain
``G`` chosen so that the RMS of ``x`` is ``vib_amplitude`` (continuous-time variance
``G^2 / (4 zeta w^3)``).  The filter is integrated in the servo loop (semi-implicit Euler) from one
standard normal number per servo cycle, drawn from the simulator's seeded generator.
"""
from __future__ import annotations

import math


def vibration_gain(amplitude: float, freq: float, zeta: float) -> float:
    """Input gain G of the band-pass so that its output RMS is ``amplitude`` (rad)."""
    w = 2.0 * math.pi * freq
    return amplitude * math.sqrt(4.0 * zeta * w ** 3)
