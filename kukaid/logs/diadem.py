"""DIAdem files as KUKA Trace writes them: a ``.dat`` text header and ``.r64`` data.

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

The ``.r64`` file is little-endian float64, interleaved: one column per explicit channel.  A
channel's value is ``raw * factor + offset``; its time is the implicit channel with as many values.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from kukaid.errors import LogFormatError


@dataclass
class Channel:
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


def parse_dat(path: Path) -> tuple[dict[int, str], list[Channel]]:
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
    channels: list[Channel] = []
    section: str | None = None
    cur: Channel | None = None
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
                cur = Channel(path, n)
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
class Signal:
    channel: Channel
    time: np.ndarray
    values: np.ndarray


def load_signals(path: Path) -> list[Signal]:
    _, channels = parse_dat(path)
    implicit: list[tuple[int, Channel, np.ndarray]] = []
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
    by_file: dict[str, list[Channel]] = {}
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
    out: list[Signal] = []
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
            out.append(Signal(ch, t, vals))
    return out
