"""Compare two demo output folders: parameter files, diagnose JSON, trajectories and logs.

Usage: python scripts/compare_demo.py BEFORE_DIR AFTER_DIR [--rtol 1e-9]

Used to show that a restructuring changed no result: every JSON file present in both folders is
compared value by value (numbers within ``rtol``, strings and keys exactly; provenance fields that
name versions, paths or times are skipped), and every HDF5 log dataset element by element. Prints
one line per file and the largest relative difference; exits 1 if anything differs.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

SKIP_KEYS = {"provenance", "kukaid_version", "created", "command", "elapsed_s", "time_s", "source_files"}


def _diff(a, b, path: str, rtol: float, out: list[str]) -> float:
    """Largest relative difference between two JSON values; differences beyond rtol go to ``out``."""
    if isinstance(a, dict) and isinstance(b, dict):
        worst = 0.0
        for k in sorted(set(a) | set(b)):
            if k in SKIP_KEYS:
                continue
            if k not in a or k not in b:
                out.append(f"{path}.{k}: only in {'after' if k in b else 'before'}")
                continue
            worst = max(worst, _diff(a[k], b[k], f"{path}.{k}", rtol, out))
        return worst
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            out.append(f"{path}: length {len(a)} vs {len(b)}")
            return math.inf
        return max([_diff(x, y, f"{path}[{i}]", rtol, out) for i, (x, y) in enumerate(zip(a, b))], default=0.0)
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        if a == b or (isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b)):
            return 0.0
        rel = abs(a - b) / max(abs(a), abs(b), 1e-300)
        if rel > rtol:
            out.append(f"{path}: {a!r} vs {b!r} (relative {rel:.2e})")
        return rel
    if a != b:
        out.append(f"{path}: {a!r} vs {b!r}")
        return math.inf
    return 0.0


def _h5(pa: Path, pb: Path, rtol: float, out: list[str]) -> float:
    import h5py

    worst = 0.0
    with h5py.File(pa, "r") as fa, h5py.File(pb, "r") as fb:
        names: list[str] = []
        fa.visit(lambda n: names.append(n) if isinstance(fa[n], h5py.Dataset) else None)
        for n in names:
            if n not in fb:
                out.append(f"{n}: missing after")
                continue
            x, y = np.asarray(fa[n][()]), np.asarray(fb[n][()])
            if x.shape != y.shape:
                out.append(f"{n}: shape {x.shape} vs {y.shape}")
                worst = math.inf
                continue
            if x.dtype.kind in "fc":
                scale = max(float(np.nanmax(np.abs(x))) if x.size else 0.0, 1e-300)
                rel = float(np.nanmax(np.abs(x - y))) / scale if x.size else 0.0
                if rel > rtol:
                    out.append(f"{n}: max relative difference {rel:.2e}")
                worst = max(worst, rel)
            elif not np.array_equal(x, y):
                out.append(f"{n}: differs")
                worst = math.inf
    return worst


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before", type=Path)
    ap.add_argument("after", type=Path)
    ap.add_argument("--rtol", type=float, default=1e-9)
    a = ap.parse_args(argv)
    bad = 0
    files = sorted(p.relative_to(a.before) for p in a.before.rglob("*") if p.suffix in (".json", ".h5"))
    for rel in files:
        pb = a.after / rel
        if not pb.exists():
            print(f"{rel}: MISSING after")
            bad += 1
            continue
        out: list[str] = []
        if rel.suffix == ".json":
            worst = _diff(json.loads((a.before / rel).read_text()), json.loads(pb.read_text()), "", a.rtol, out)
        else:
            worst = _h5(a.before / rel, pb, a.rtol, out)
        status = "identical" if worst == 0 else ("equal within rtol" if not out else "DIFFERENT")
        print(f"{rel}: {status} (largest relative difference {worst:.2e})")
        for line in out[:10]:
            print(f"    {line}")
        bad += bool(out)
    print(f"{len(files)} files compared, {bad} differ")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
