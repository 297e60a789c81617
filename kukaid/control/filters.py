"""Causal (online) filtering: the paper's 3rd-order Butterworth low-pass, one sample at a time.

Offline identification filters forward and backward (zero phase); a controller cannot look ahead,
so the torque-residual estimator uses the causal filter below.  Its delay at low frequency is the
group delay of the filter (about 2/(2 pi fc) = 64 ms for the 3rd-order 5 Hz filter); every signal
that enters one residual passes through the same filter, so they stay aligned.
"""
from __future__ import annotations

import cmath
import math

import numpy as np

from kukaid.errors import KukaidError


class CausalButterworth:
    """Causal Butterworth low-pass of order ``order`` and cut-off ``cutoff`` Hz at ``fs`` Hz (or,
    with ``btype="bandpass"``, a band-pass between the two frequencies of ``cutoff``).

    ``step(x)`` filters one sample.  The first sample initialises the state at steady state
    (output = input), so a filter switched on at a non-zero level has no start-up transient.
    """

    def __init__(self, cutoff: float | tuple[float, float] = 5.0, fs: float = 1.0 / 0.012, order: int = 3,
                 btype: str = "lowpass") -> None:
        from scipy.signal import butter, sosfilt_zi

        if not (math.isfinite(fs) and fs > 0):
            raise KukaidError(f"filter: sample rate must be > 0 Hz, got {fs}")
        cuts = (cutoff,) if btype == "lowpass" else tuple(cutoff)  # type: ignore[arg-type]
        if btype not in ("lowpass", "bandpass") or not all(math.isfinite(c) and 0 < c < fs / 2 for c in cuts):
            raise KukaidError(f"filter: cut-off {cutoff} Hz must be in (0, {fs / 2:g}) Hz (Nyquist of {fs:g} Hz)")
        if not (isinstance(order, int) and 1 <= order <= 8):
            raise KukaidError(f"filter: order must be an integer 1 to 8, got {order}")
        self.cutoff, self.fs, self.order = cutoff, float(fs), order
        self._sos = butter(order, cutoff, btype=btype, fs=fs, output="sos")
        self._zi0 = sosfilt_zi(self._sos)  # steady state for a unit step
        # direct-form II transposed sections, unrolled into plain floats (fast per-sample steps)
        self._b = [tuple(float(v) for v in s[:3]) for s in self._sos]
        self._a = [tuple(float(v) for v in s[4:6]) for s in self._sos]
        self._z: list[list[float]] | None = None

    def reset(self, x0: float | None = None) -> None:
        """Forget the state; with ``x0`` start at steady state on that value."""
        self._z = None if x0 is None else [[float(v) * x0 for v in zi] for zi in self._zi0]

    def step(self, x: float) -> float:
        x = float(x)
        if self._z is None:
            self.reset(x)
        y = x
        for (b0, b1, b2), (a1, a2), z in zip(self._b, self._a, self._z):
            out = b0 * y + z[0]
            z[0] = b1 * y - a1 * out + z[1]
            z[1] = b2 * y - a2 * out
            y = out
        return y

    def phase_delay(self, w: float) -> float:
        """The filter's phase delay at ``w`` rad/s: -(phase of its response) / w, s (the response of
        each section at e^{jωT} in plain complex numbers: called within a control step)."""
        f = min(max(float(w), 1e-6) / (2 * math.pi), 0.499 * self.fs)
        z1 = cmath.exp(-2j * math.pi * f / self.fs)  # z^-1
        h = 1.0 + 0j
        for (b0, b1, b2), (a1, a2) in zip(self._b, self._a):
            h *= (b0 + z1 * (b1 + z1 * b2)) / (1.0 + z1 * (a1 + z1 * a2))
        return ((-cmath.phase(h)) % (2 * math.pi)) / (2 * math.pi * f)

    def filter(self, x: np.ndarray) -> np.ndarray:
        """Filter a whole array causally (from the present state)."""
        return np.array([self.step(v) for v in np.asarray(x, dtype=float).ravel()])
