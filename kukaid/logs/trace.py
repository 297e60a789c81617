"""KUKA Trace recordings (KR C4): DIAdem ``.dat`` headers with ``.r64`` data files -> AxisLog.

The ``.dat`` file is DIAdem text: a first line starting ``DIAEXTENDED``, a global header
(``#BEGINGLOBALHEADER`` .. ``#ENDGLOBALHEADER``) and one channel header per channel
(``#BEGINCHANNELHEADER`` .. ``#ENDCHANNELHEADER``) made of ``code,value`` lines:

====  ===========================================================================
200   channel name                      202  unit
210   ``EXPLIZIT`` (values in a data file) or ``IMPLIZIT`` (time: start + i*step)
211   data file (``.r64``)              214  data type (``REAL64`` only)
220   number of values                  221  column pointer (1-based) in the data file
222   values per row (optional; default: the number of columns the file holds)
240   offset (explicit) / start (implicit)
241   factor (explicit) / step (implicit)
====  ===========================================================================

The ``.r64`` file is little-endian float64, interleaved: one column per explicit channel.

A recording is usually several modules (one ``.dat``/``.r64`` pair each, e.g.
``REC_KRCIpo.dat`` and ``REC_NextGenDrive#1.dat``) with different sample times.  Given one of
them, :func:`read_trace` also reads its siblings ``REC_*.dat`` and puts every channel on one time
base (by default that of the measured position; other channels are interpolated linearly over
the interval all channels cover).

Channel mapping (case-insensitive; axis number from ``A3``, ``Achse 3``, ``Axis 3`` or a trailing
number):

- measured position ``q``: ``Istposition``, ``Ist-Position``, ``Position_Ist``, ``AxisPos_Act``,
  ``ActPos``;
- commanded position ``q_cmd``: ``Sollposition``, ``Position_Soll``, ``AxisPos_Cmd``/``_Set``,
  and the plain axis-position channels of a ``KRCIpo`` module (the interpolator's setpoints);
- torque ``tau``: ``Istmoment``, ``Ist-Moment``, ``Moment_Ist``, ``Torque_Act``, ``ActTorque``;
- motor temperature ``temp``: ``Motortemperatur``, ``MotorTemp``.

Units (202): degrees (``Grad``, ``°``, ``deg``) or ``rad``; ``mm``/``m`` for a linear axis;
``Nm``/``N``; ``°C`` or ``K``.  Anything else is an error naming the channel.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from kukaid.errors import LogFormatError

if TYPE_CHECKING:
    from kukaid.logs.axislog import AxisLog

_DEG = math.pi / 180.0


@dataclass
class _Channel:
    file: Path
    line: int  # line of #BEGINCHANNELHEADER
    codes: dict[int, str] = field(default_factory=dict)
    code_lines: dict[int, int] = field(default_factory=dict)

    @property
    def name(self) -> str:
        return self.codes.get(200, "").strip() or f"<unnamed channel at line {self.line}>"

    def where(self, code: int | None = None) -> str:
        ln = self.code_lines.get(code, self.line) if code is not None else self.line
        return f"{self.file}: line {ln}: channel '{self.name}'"

    def num(self, code: int, kind=float, default=None):
        if code not in self.codes or not self.codes[code].strip():
            if default is not None:
                return default
            raise LogFormatError(f"{self.where()}: missing code {code}")
        txt = self.codes[code].strip().replace("D", "E").replace("d", "e")
        try:
            v = kind(float(txt)) if kind is int else float(txt)
        except ValueError:
            raise LogFormatError(f"{self.where(code)}: code {code} value '{self.codes[code].strip()}' "
                                 "is not a number") from None
        if not math.isfinite(v):
            raise LogFormatError(f"{self.where(code)}: code {code} is not finite")
        if kind is int and float(txt) != int(float(txt)):
            raise LogFormatError(f"{self.where(code)}: code {code} value '{self.codes[code].strip()}' "
                                 "is not an integer")
        return v

    @property
    def kind(self) -> str:
        k = self.codes.get(210, "").strip().upper()
        if k not in ("EXPLIZIT", "IMPLIZIT"):
            raise LogFormatError(f"{self.where(210)}: code 210 must be EXPLIZIT or IMPLIZIT, got '{k}'")
        return k


def parse_dat(path: Path) -> tuple[dict[int, str], list[_Channel]]:
    """Parse a DIAdem header: (global header codes, channels).  Errors name the line."""
    try:
        text = path.read_bytes().decode("latin-1")
    except OSError as e:
        raise LogFormatError(f"{path}: cannot read ({e.strerror or e})") from None
    lines = text.splitlines()
    first = next((i for i, ln in enumerate(lines) if ln.strip()), None)
    if first is None:
        raise LogFormatError(f"{path}: empty file (expected a DIAdem header starting with DIAEXTENDED)")
    if not lines[first].strip().upper().startswith("DIAEXTENDED"):
        raise LogFormatError(f"{path}: line {first + 1}: not a KUKA Trace/DIAdem header "
                             f"(expected DIAEXTENDED, found '{lines[first].strip()[:40]}')")
    glob: dict[int, str] = {}
    channels: list[_Channel] = []
    section: str | None = None
    cur: _Channel | None = None
    start = 0
    for i in range(first + 1, len(lines)):
        ln = lines[i].strip()
        n = i + 1
        if not ln:
            continue
        up = ln.upper()
        if up.startswith("#BEGIN"):
            if section is not None:
                raise LogFormatError(f"{path}: line {n}: {ln} inside the section opened at line {start} "
                                     f"(missing #END{section})")
            if up == "#BEGINGLOBALHEADER":
                section = "GLOBALHEADER"
            elif up == "#BEGINCHANNELHEADER":
                section = "CHANNELHEADER"
                cur = _Channel(path, n)
            else:
                raise LogFormatError(f"{path}: line {n}: unknown section '{ln}'")
            start = n
            continue
        if up.startswith("#END"):
            if section is None or up != f"#END{section}":
                raise LogFormatError(f"{path}: line {n}: '{ln}' does not close an open section")
            if section == "CHANNELHEADER":
                assert cur is not None
                channels.append(cur)
                cur = None
            section = None
            continue
        if section is None:
            raise LogFormatError(f"{path}: line {n}: '{ln[:40]}' is outside any header section")
        code, sep, value = ln.partition(",")
        if not sep or not code.strip().isdigit():
            raise LogFormatError(f"{path}: line {n}: expected 'code,value', found '{ln[:40]}'")
        if section == "GLOBALHEADER":
            glob[int(code)] = value
        else:
            assert cur is not None
            cur.codes[int(code)] = value
            cur.code_lines[int(code)] = n
    if section is not None:
        raise LogFormatError(f"{path}: the section opened at line {start} is never closed (missing #END{section})")
    if not channels:
        raise LogFormatError(f"{path}: no channel headers (#BEGINCHANNELHEADER)")
    return glob, channels


@dataclass
class _Signal:
    channel: _Channel
    time: np.ndarray
    values: np.ndarray


def _load_signals(path: Path) -> list[_Signal]:
    _, channels = parse_dat(path)
    implicit: list[tuple[int, _Channel, np.ndarray]] = []
    for idx, ch in enumerate(channels):
        if ch.kind == "IMPLIZIT":
            n = ch.num(220, int)
            step = ch.num(241)
            if n < 1 or not step > 0:
                raise LogFormatError(f"{ch.where()}: time channel needs 220 >= 1 and step 241 > 0 "
                                     f"(got {n}, {step})")
            implicit.append((idx, ch, ch.num(240, default=0.0) + step * np.arange(n)))
    explicit = [(i, ch) for i, ch in enumerate(channels) if ch.kind == "EXPLIZIT"]
    # data files: one column per explicit channel
    by_file: dict[str, list[_Channel]] = {}
    for _, ch in explicit:
        fname = ch.codes.get(211, "").strip()
        if not fname:
            raise LogFormatError(f"{ch.where()}: missing code 211 (data file)")
        dtype = ch.codes.get(214, "").strip().upper()
        if dtype != "REAL64":
            raise LogFormatError(f"{ch.where(214)}: data type '{dtype}' is not supported (REAL64 only)")
        by_file.setdefault(fname, []).append(ch)
    for fname, chans in by_file.items():
        if not (path.parent / Path(fname.replace("\\", "/")).name).exists():
            raise LogFormatError(f"{chans[0].where(211)}: data file '{Path(fname).name}' not found beside {path.name}")
    out: list[_Signal] = []
    for fname, chans in by_file.items():
        dpath = path.parent / Path(fname.replace("\\", "/")).name
        counts = {ch.num(220, int) for ch in chans}
        if len(counts) != 1:
            raise LogFormatError(f"{chans[0].where(220)}: channels of '{dpath.name}' disagree on the number of "
                                 f"values (220): {sorted(counts)}")
        n = counts.pop()
        cols = [ch.num(221, int) for ch in chans]
        stride = max(int(ch.num(222, int, default=0)) for ch in chans) or max(max(cols), len(chans))
        for ch, c in zip(chans, cols):
            if not 1 <= c <= stride:
                raise LogFormatError(f"{ch.where(221)}: column pointer {c} outside 1..{stride}")
        size = dpath.stat().st_size
        want = n * stride * 8
        if size != want:
            raise LogFormatError(
                f"{dpath}: {size} bytes, but channel '{chans[0].name}' and the other {len(chans) - 1} channel(s) "
                f"of this file need {n} values x {stride} columns x 8 bytes = {want} bytes")
        data = np.fromfile(dpath, dtype="<f8").reshape(n, stride)
        for ch, c in zip(chans, cols):
            vals = data[:, c - 1] * ch.num(241, default=1.0) + ch.num(240, default=0.0)
            bad = np.flatnonzero(~np.isfinite(vals))
            if bad.size:
                raise LogFormatError(f"{ch.where()}: value {bad[0] + 1} is not a finite number")
            pos = channels.index(ch)
            cands = [(i, t) for i, c2, t in implicit if t.size == n]
            before = [(i, t) for i, t in cands if i < pos]
            if not cands:
                raise LogFormatError(f"{ch.where()}: no time channel (IMPLIZIT) with {n} values in {path.name}")
            t = (before[-1] if before else cands[0])[1]
            out.append(_Signal(ch, t, vals))
    return out


# -- mapping ------------------------------------------------------------------------------------
_KEYS = [  # (pattern, quantity)
    (r"soll[-_ ]?pos|sollposition|position[-_ ]?soll|axispos[-_ ]?(cmd|set)|cmdpos|setpos", "q_cmd"),
    (r"ist[-_ ]?pos|istposition|position[-_ ]?ist|axispos[-_ ]?act|actpos|measpos", "q"),
    (r"ist[-_ ]?moment|istmoment|moment[-_ ]?ist|torque[-_ ]?act|acttorque|istdrehmoment", "tau"),
    (r"motor[-_ ]?temp", "temp"),
]
_AXIS_RES = [re.compile(r"(?:^|[^a-z])a(\d{1,2})(?![0-9])", re.I), re.compile(r"achse\s*(\d{1,2})", re.I),
             re.compile(r"axis\s*(\d{1,2})", re.I), re.compile(r"(\d{1,2})\s*$")]
_GENERIC_POS = re.compile(r"pos", re.I)


def _axis_of(name: str) -> int | None:
    for rx in _AXIS_RES:
        m = rx.search(name)
        if m:
            a = int(m.group(1))
            if 1 <= a <= 12:
                return a
    return None


def _classify(sig: _Signal, module: str) -> tuple[str, int] | None:
    name = sig.channel.name
    low = name.lower()
    qty = next((q for rx, q in _KEYS if re.search(rx, low)), None)
    if qty is None and "krcipo" in module.lower() and _GENERIC_POS.search(low):
        qty = "q_cmd"  # the interpolator's axis channels are setpoints
    if qty is None:
        return None
    axis = _axis_of(name)
    if axis is None:
        return None
    return qty, axis


def _to_si(sig: _Signal, qty: str) -> tuple[np.ndarray, str]:
    unit = sig.channel.codes.get(202, "").strip()
    u = unit.lower().replace(" ", "")
    v = sig.values
    if qty in ("q", "q_cmd"):
        if u in ("grad", "°", "deg", "grd", "degree", "degrees"):
            return v * _DEG, "revolute"
        if u == "rad":
            return v, "revolute"
        if u == "mm":
            return v * 1e-3, "prismatic"
        if u == "m":
            return v, "prismatic"
    elif qty == "tau":
        if u in ("nm", "n*m", "n·m"):
            return v, "revolute"
        if u == "n":
            return v, "prismatic"
    elif qty == "temp":
        if u in ("°c", "c", "gradc", "degc", "grad", "°"):
            return v, ""
        if u == "k":
            return v - 273.15, ""
    raise LogFormatError(f"{sig.channel.where(202)}: unit '{unit}' is not supported for {qty}")


def _siblings(path: Path) -> list[Path]:
    m = re.match(r"^(.*)_[^_]+$", path.stem)
    if not m:
        return [path]
    prefix = m.group(1)
    sib = sorted(p for p in path.parent.glob("*.dat")
                 if p.stem.startswith(prefix + "_") and "_" not in p.stem[len(prefix) + 1:] or p == path)
    return sib or [path]


def read_trace(path: str | Path, *, siblings: bool = True, time_base: str = "position") -> "AxisLog":
    """Read a KUKA Trace recording into an :class:`~kukaid.logs.axislog.AxisLog` (SI units).

    Parameters
    ----------
    path : one ``.dat`` file of the recording.
    siblings : also read the recording's other modules (``PREFIX_*.dat`` beside ``path``).
    time_base : "position" (the sample instants of the measured position) or "finest" (the
        shortest sample time among the mapped channels).

    Every axis with both a measured position and a torque channel is logged; commanded
    position and motor temperature are added when present for every logged axis.
    """
    from kukaid.logs.axislog import AxisLog

    path = Path(path)
    if not path.exists():
        raise LogFormatError(f"{path}: no such file")
    if time_base not in ("position", "finest"):
        raise LogFormatError(f"time_base must be 'position' or 'finest', got {time_base!r}")
    files = _siblings(path) if siblings else [path]
    mapped: dict[tuple[str, int], tuple[_Signal, np.ndarray]] = {}
    joint_of: dict[int, str] = {}
    names: list[str] = []
    for f in files:
        module = f.stem
        for sig in _load_signals(f):
            names.append(sig.channel.name)
            c = _classify(sig, module)
            if c is None:
                continue
            qty, axis = c
            if (qty, axis) in mapped:
                prev = mapped[(qty, axis)][0].channel
                raise LogFormatError(f"{sig.channel.where()}: A{axis} already has a {qty} channel "
                                     f"('{prev.name}' in {prev.file.name}); keep one of them")
            vals, joint = _to_si(sig, qty)
            if joint:
                if joint_of.setdefault(axis, joint) != joint:
                    raise LogFormatError(f"{sig.channel.where(202)}: A{axis} mixes revolute and linear units")
            mapped[(qty, axis)] = (sig, vals)
    axes = sorted({a for q, a in mapped if q == "q"} & {a for q, a in mapped if q == "tau"})
    if not axes:
        raise LogFormatError(f"{path}: no axis has both a measured position (Istposition) and a torque "
                             f"(Istmoment) channel; channels: {names[:12]}")
    used = [(k, v) for k, v in mapped.items() if k[1] in axes]
    t_lo = max(v[0].time[0] for _, v in used)
    t_hi = min(v[0].time[-1] for _, v in used)
    if not t_hi > t_lo:
        raise LogFormatError(f"{path}: the channels' time ranges do not overlap")
    if time_base == "position":
        base = mapped[("q", axes[0])][0].time
    else:
        base = min((v[0].time for _, v in used), key=lambda t: np.median(np.diff(t)) if t.size > 1 else np.inf)
    eps = 1e-9 * max(1.0, abs(t_hi))
    time = base[(base >= t_lo - eps) & (base <= t_hi + eps)]
    if time.size < 2:
        raise LogFormatError(f"{path}: fewer than 2 samples where all channels overlap")
    data: dict[str, np.ndarray | None] = {}
    for qty in ("q", "tau", "q_cmd", "temp"):
        if not all((qty, a) in mapped for a in axes):
            data[qty] = None
            continue
        cols = []
        for a in axes:
            sig, vals = mapped[(qty, a)]
            cols.append(vals if sig.time is base and time.size == base.size else np.interp(time, sig.time, vals))
        data[qty] = np.column_stack(cols)
    joint = tuple(joint_of.get(a, "revolute") for a in axes)
    attrs: dict[str, Any] = {
        "source": "kuka-trace",
        "source_file": str(path),
        "trace_files": [str(f) for f in files],
        "trace_channels": {f"{q} A{a}": f"{s.channel.name} ({s.channel.file.name})"
                           for (q, a), (s, _) in mapped.items() if a in axes},
        "time_base": time_base,
    }
    return AxisLog(time=time, axes=tuple(axes), joint=joint, attrs=attrs, **data)
