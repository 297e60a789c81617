"""kukaid fleet diagnose over whole-arm logs (fleet fit --robot): each log diagnosed as
``kukaid diagnose --params robot.json`` does (the same function), one row per log and joint; a
log that fails, whether unreadable or in its diagnosis, is an error row and the others complete."""
from __future__ import annotations

import csv
import json
import subprocess

import pytest

from fleet_helpers import rippled_arm_log, small_fleet

from kukaid.fleet.table import read_table, write_table

CB_LOG = "arm/R002/2026-01-05.h5"      # a position ripple on A4 the URDF does not know
BAD_LOG = "arm/R003/2026-01-05.h5"     # a simulated arm log cut in half


def _run(cmd, *args, timeout=300):
    return subprocess.run([*cmd, *map(str, args)], capture_output=True, text=True, timeout=timeout)


@pytest.fixture(scope="module")
def arms(tmp_path_factory, kukaid_cmd):
    """Three simulated whole-arm logs (R001, three days), one with a position ripple on A4, one truncated;
    fitted with fleet fit --robot and diagnosed with fleet diagnose (one local worker)."""
    out = tmp_path_factory.mktemp("arms")
    man = small_fleet(out, robots=1, days=3, seed=23, whole_arm=True)
    with open(man, newline="") as f:
        first = next(csv.DictReader(f))["path"]
    rippled_arm_log(out / CB_LOG)
    data = (out / first).read_bytes()
    (out / BAD_LOG).parent.mkdir(parents=True)
    (out / BAD_LOG).write_bytes(data[: len(data) // 2])
    with open(man, "a", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(("R002", "", "2026-01-05", CB_LOG))
        w.writerow(("R003", "", "2026-01-05", BAD_LOG))
    fit, dia = out / "fit.parquet", out / "diagnose.parquet"
    r = _run(kukaid_cmd, "fleet", "fit", man, "--robot", "kr6-r700-sixx", "-o", fit, "--workers", "1")
    assert r.returncode == 0, r.stderr
    r = _run(kukaid_cmd, "fleet", "diagnose", man, "--table", fit, "-o", dia, "--workers", "1")
    assert r.returncode == 0, r.stderr
    return out, man, fit, dia


def test_whole_arm_logs_are_diagnosed_per_joint_and_a_corrupt_one_is_an_error_row(arms):
    out, _, _, dia = arms
    rows, settings = read_table(dia)
    assert settings["task"] == "diagnose"
    by_log: dict[str, list[dict]] = {}
    for r in rows:
        by_log.setdefault(r["path"], []).append(r)
    assert len(by_log) == 5                                 # three simulated, the rippled, the corrupt
    bad = by_log.pop(BAD_LOG)
    assert len(bad) == 1 and bad[0]["status"] == "error" and "truncated" in bad[0]["error"]
    for path, rs in by_log.items():
        assert [r["status"] for r in rs] == ["ok"] * 6, (path, [r["error"] for r in rs])
        assert [r["axis"] for r in rs] == [1, 2, 3, 4, 5, 6] and all(r["kind"] == "diagnose" for r in rs)
        assert all(0 < r["rel_error"] < 0.5 and r["effects"] is not None for r in rs)
        results = [json.loads(r["result"]) for r in rs if r["result"]]
        assert len(results) == 1 and results[0]["schema"] == "kukaid.robot_diagnosis/1"
        assert [r["rel_error"] for r in rs] == pytest.approx(results[0]["heldout_relative_error_after"])
        named = [s["name"] for s in results[0]["steps"]]
        if path == CB_LOG:
            assert named == ["position_ripple@A4"]
            assert [r["effects"] for r in rs] == ["", "", "", "position_ripple@A4", "", ""]
        else:                                               # simulated logs: the fit's model is the truth's
            assert named == [] and all(r["effects"] == "" for r in rs)
            assert rs[0]["temp_mean"] is not None


def test_fleet_row_is_what_kukaid_diagnose_says_of_the_log(arms, kukaid_cmd, tmp_path):
    out, _, fit, dia = arms
    params = next(r["result"] for r in read_table(fit)[0] if r["path"] == CB_LOG and r["result"])
    (tmp_path / "arm.json").write_text(params)
    r = _run(kukaid_cmd, "diagnose", "--params", tmp_path / "arm.json", "--log", out / CB_LOG, "--json")
    assert r.returncode == 0, r.stderr
    single = json.loads(r.stdout)
    fleet = json.loads(next(x["result"] for x in read_table(dia)[0] if x["path"] == CB_LOG and x["result"]))
    assert [s["name"] for s in fleet["steps"]] == [s["name"] for s in single["steps"]] == ["position_ripple@A4"]
    for key in ("relative_error_given", "heldout_relative_error_before", "heldout_relative_error_after"):
        assert fleet[key] == pytest.approx(single[key], rel=1e-9)


@pytest.mark.parametrize("max_steps", [0, pytest.param(4, marks=pytest.mark.slow)])
def test_a_whole_arm_log_whose_diagnosis_fails_is_an_error_row(arms, tmp_path, max_steps):
    """In-process (no cluster): the fit of one log names a URDF other than the robot's, so its
    diagnosis raises; that log is one error row, the others are diagnosed. With no candidate tried
    (--max-steps 0: the three others' rows in 2 s, not 15) in the default suite; as fleet diagnose
    runs them (4) with -m slow."""
    import functools

    from kukaid.diagnose import diagnose_model
    from kukaid.fleet.manifest import read_input
    from kukaid.fleet.run import plan
    from kukaid.fleet.tasks import CheckOptions, check_task

    out, man, fit, _ = arms
    rows, settings = read_table(fit)
    for r in rows:
        if r["path"] == CB_LOG and r["result"]:
            p = json.loads(r["result"])
            p["robot"]["sha256"] = "0" * 64
            r["result"] = json.dumps(p)
    table = tmp_path / "fit.parquet"
    write_table(table, rows, settings)
    jobs = plan(read_input(man), [], "diagnose")[0]
    opts = CheckOptions(table=str(table), kind="diagnose", run=functools.partial(diagnose_model, max_steps=max_steps))
    got = {j.name: check_task(j, opts) for j in jobs}
    cb = got.pop(CB_LOG)
    assert [r["status"] for r in cb] == ["error"] and "not the one the parameters were fitted with" in cb[0]["error"]
    assert [r["status"] for r in got.pop(BAD_LOG)] == ["error"]
    assert len(got) == 3 and all([r["status"] for r in rs] == ["ok"] * 6 for rs in got.values())


def test_a_friction_term_on_its_bound_is_zero_in_the_fleet_table():
    """New-user trial 15: `fleet fit --robot kuka_lwr4.urdf` of the LWR4+ recordings wrote Fv = -8.4e-09 N·m·s/rad
    (a negative viscous friction) for the joints whose Fv ended on its bound 0, which fit, show and report print
    as 0: the table now holds the bound's value."""
    from shared_data import SHARED

    from kukaid.fleet.manifest import content_hash
    from kukaid.fleet.tasks import FitOptions, Job, fit_task

    lwr4 = SHARED / "datasets" / "lwr4"
    if not lwr4.is_dir():
        pytest.skip("real LWR4+ data (../shared/datasets/lwr4) not present")
    log = lwr4 / "lwr4_1.csv"
    job = Job("lwr", None, "2026-01-01", str(log), "lwr/2026-01-01/arm.csv", content_hash(log))
    rows = fit_task(job, FitOptions(robot=str(lwr4 / "kuka_lwr4.urdf")))
    assert [r["status"] for r in rows] == ["ok"] * 7, rows[0]["error"]
    at = set(json.loads(rows[0]["result"])["metrics"]["at_bound"])
    on = [(r["axis"], n) for r in rows for n in ("Fc", "Fv") if f"A{r['axis']}.{n}" in at]
    assert on and all(rows[a - 1][n] == 0.0 for a, n in on), on
    assert all(r[n] >= 0 for r in rows for n in ("Fc", "Fv"))
