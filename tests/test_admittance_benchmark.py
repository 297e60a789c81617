"""The admittance benchmarks at their --quick size: they run on the plant family and report issue
22's acceptance lines (the figures themselves come from the full runs, docs/admittance.md)."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_admittance_benchmark_quick_runs_on_the_plant_family():
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "admittance_paper.py"), "--quick", "--json",
                          "--jobs", "1"], capture_output=True, text=True, check=True, timeout=600)
    doc = json.loads(out.stdout)
    assert doc["plants"] == "family"
    res = doc["results"]["0.024"]
    runs = res["runs"]
    assert {r["plant"] for r in runs["adaptive"]} == {"gms"}  # operators 0-2 meet the first member
    assert len(runs["D50"]) == len(runs["adaptive"]) == 3
    assert len(runs["D150"]) == 1                             # the firm references meet firm grips only
    lines = [a["line"] for a in doc["acceptance"]]
    assert any("lightest stable constant D" in line for line in lines)
    assert any("detections after any release" in line for line in lines)


def test_rest_benchmark_quick_reports_every_run():
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "admittance_rest.py"), "--quick", "--json",
                          "--jobs", "1"], capture_output=True, text=True, check=True, timeout=600)
    doc = json.loads(out.stdout)
    assert len(doc["runs"]) == 16 and len(doc["summary"]) == 4
    assert {r["plant"] for r in doc["runs"]} == {"gms", "lugre"}
    assert all(r["passes"] for r in doc["runs"]), [r for r in doc["runs"] if not r["passes"]]


def test_rest_benchmark_outside_the_family_reports_a_row_per_change():
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "admittance_rest.py"), "--quick", "--json",
                          "--jobs", "1", "--outside", "stiction,jitter"], capture_output=True, text=True, check=True,
                         timeout=600)
    doc = json.loads(out.stdout)
    assert len(doc["runs"]) == 32
    assert [(r["outside"], r["scenario"]) for r in doc["summary"]] == [
        ("stiction", "rest"), ("stiction", "after a guided move"), ("jitter", "rest"), ("jitter", "after a guided move")]
    assert all(r["passes"] for r in doc["runs"]), [r for r in doc["runs"] if not r["passes"]]
    bad = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "admittance_rest.py"), "--outside", "frost"],
                         capture_output=True, text=True)
    assert bad.returncode == 2 and "unknown change 'frost'" in bad.stderr


def test_rest_benchmark_with_the_files_the_toolkits_identification_gives():
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "admittance_rest.py"), "--quick", "--json",
                          "--jobs", "1", "--files", "fitted"], capture_output=True, text=True, check=True, timeout=600)
    doc = json.loads(out.stdout)
    assert doc["files"] == "fitted" and len(doc["runs"]) == 16
    assert all(r["passes"] for r in doc["runs"]), [r for r in doc["runs"] if not r["passes"]]
