"""Write KUKA Trace recordings (DIAdem ``.dat`` header + ``.r64`` data) from known signals.

:func:`write_module` writes one module; :func:`write_kr_c4_set` a recording as a KR C4 writes
it: one ``<name>_NextGenDrive#N`` module per drive (motor-side position, torque, temperature and a
current channel, no axis number in the channel names, 1 ms) and ``<name>_KRCIpo`` (the
interpolator's joint setpoints, 12 ms, starting later and ending earlier), every channel stored
as raw numbers with its own factor (code 241) and offset (code 240).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


def write_module(folder: Path, stem: str, step: float, n: int, channels: list[tuple], start: float = 0.0,
                 r64_name: str | None = None, extra_lines: dict | None = None) -> Path:
    """Write STEM.dat + STEM.r64 (interleaved little-endian float64, one column per channel).

    ``channels``: ``(name, unit, raw)`` or ``(name, unit, raw, factor, offset)``; the value a
    reader must give is ``raw * factor + offset``.  ``extra_lines`` edits the header text
    (old -> new) to make malformed files.
    """
    r64 = r64_name or f"{stem}.r64"
    lines = ["DIAEXTENDED  {@:ENGLISH", "", "#BEGINGLOBALHEADER", "1,WINDOWS 32Bit", "101,KRC-Trace",
             "104,11.22.2026", "#ENDGLOBALHEADER",
             "#BEGINCHANNELHEADER", "200,Zeit", "202,s", "210,IMPLIZIT", "213,BLOCK", "214,REAL64",
             f"220,{n}", f"240,{start!r}", f"241,{step!r}", "#ENDCHANNELHEADER"]
    for j, ch in enumerate(channels, start=1):
        name, unit, _, factor, offset = (*ch, 1.0, 0.0) if len(ch) == 3 else ch
        lines += ["#BEGINCHANNELHEADER", f"200,{name}", "201,", f"202,{unit}", "210,EXPLIZIT", f"211,{r64}",
                  "213,BLOCK", "214,REAL64", "215,INTEL", f"220,{n}", f"221,{j}",
                  f"240,{offset!r}" if len(ch) > 3 else "240,0.0", f"241,{factor!r}" if len(ch) > 3 else "241,1.0",
                  "#ENDCHANNELHEADER"]
    text = "\n".join(lines) + "\n"
    for k, v in (extra_lines or {}).items():
        text = text.replace(k, v)
    (folder / f"{stem}.dat").write_bytes(text.encode("latin-1"))
    np.column_stack([c[2] for c in channels]).astype("<f8").tofile(folder / r64)
    return folder / f"{stem}.dat"


#: motor turns per axis turn of a large six-axis robot (signs as KUKA machine data may have them)
GEAR = {1: -161.0, 2: 153.0, 3: 153.0, 4: -93.6, 5: 101.5, 6: -72.0}


@dataclass
class TraceSet:
    """What :func:`write_kr_c4_set` wrote: the files and, per axis, the raw numbers and scalings."""

    folder: Path
    name: str
    t_drive: np.ndarray
    t_ipo: np.ndarray
    raw: dict[tuple[str, int], np.ndarray] = field(default_factory=dict)  # (channel, axis) -> raw
    scale: dict[tuple[str, int], tuple[float, float]] = field(default_factory=dict)  # -> (factor, offset)
    q_joint_deg: dict[int, np.ndarray] = field(default_factory=dict)  # true joint angle, deg, on t_drive
    tau_joint: dict[int, np.ndarray] = field(default_factory=dict)  # true joint torque, N·m, on t_drive

    def value(self, channel: str, axis: int) -> np.ndarray:
        """The channel's value in the file's unit: raw * factor + offset."""
        f, o = self.scale[(channel, axis)]
        return self.raw[(channel, axis)] * f + o

    def dat(self, module: str) -> Path:
        return self.folder / f"{self.name}_{module}.dat"


def write_kr_c4_set(folder: Path, name: str = "Rec", duration: float = 1.5, drive_dt: float = 0.001,
                    ipo_dt: float = 0.012, seed: int = 7) -> TraceSet:
    """Six ``NextGenDrive#N`` modules and a ``KRCIpo`` module from known joint motions."""
    rng = np.random.default_rng(seed)
    td = np.arange(int(round(duration / drive_dt))) * drive_dt
    ti = np.arange(1, int(round(duration / ipo_dt)) - 1) * ipo_dt  # 12 ms, one tick later, ends earlier
    ts = TraceSet(folder, name, td, ti)
    ipo = []
    for a in range(1, 7):
        amp, per, c = rng.uniform(5, 40), rng.uniform(0.8, 3.0), rng.uniform(-60, 60)
        qj = c + amp * np.sin(2 * np.pi * td / per)  # joint angle, deg
        tau_j = rng.uniform(-800, 800) + rng.uniform(50, 400) * np.cos(2 * np.pi * td / per)  # N·m
        ts.q_joint_deg[a], ts.tau_joint[a] = qj, tau_j
        r = GEAR[a]
        # raw numbers as a drive stores them: counts with a factor and an offset per channel
        spec = {"Istposition": (qj * r, 1e-4 * (1 + a), 12.5 * a, "Grad"),
                "Istmoment": (tau_j / r, 1e-3 * (2 + a), -0.75 * a, "Nm"),
                "Motortemperatur": (35.0 + a + 0.01 * td, 0.1, 0.0, "°C"),
                "Iststrom": (rng.normal(0, 1, td.size), 1.0, 0.0, "A")}
        chans = []
        for ch, (value, f, o, unit) in spec.items():
            raw = np.round((value - o) / f)
            ts.raw[(ch, a)], ts.scale[(ch, a)] = raw, (f, o)
            chans.append((ch, unit, raw, f, o))
        write_module(folder, f"{name}_NextGenDrive#{a}", drive_dt, td.size, chans)
        qc = c + amp * np.sin(2 * np.pi * (ti - 0.004) / per)  # setpoints lead the measurement by 4 ms
        f, o = 1e-5, -1.0 * a
        raw = np.round((qc - o) / f)
        ts.raw[("Sollposition", a)], ts.scale[("Sollposition", a)] = raw, (f, o)
        ipo.append((f"Sollposition A{a}", "Grad", raw, f, o))
    write_module(folder, f"{name}_KRCIpo", ipo_dt, ti.size, ipo, start=float(ti[0]))
    return ts


DEG = math.pi / 180.0
