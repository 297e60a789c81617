"""The fleet benchmarks run at their --quick size (so they do not rot); the figures they print are
not asserted here (wall times depend on the machine), only that they run and report."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _bench(name: str) -> dict:
    r = subprocess.run([sys.executable, str(ROOT / "benchmarks" / name), "--quick", "--json"], capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    return json.loads(r.stdout)


def test_fleet_scaling_quick():
    out = _bench("fleet_scaling.py")
    run = out["runs"][0]
    assert run["kind"] == "one-axis" and run["logs"] == 4 and run["errors"] == 0 and run["peak_worker_mb"] > 0


def test_fleet_wear_quick():
    out = _bench("fleet_wear.py")
    tot = out["total"]
    assert tot["axes"] == 6 and tot["wearing"] >= 1
    assert {r["verdict"] for r in out["runs"]} == {"temperature model", "no temperature model"}
