"""End to end on the six-axis virtual KR C4: excite fourier -> capture -> fit --robot -> validate.

Run:  python benchmarks/robot_identification_e2e.py [--out DIR] [--kukaid CMD] [--fit-kukaid CMD] [--robot URDF]
          [--rotor | --coupled] [--json]

Two Fourier excitations of every axis of the bundled KR 6 R700 sixx (different seeds, harmonics
and periods), each captured on the six-axis simulator (the same seeded robot, truth away from
the URDF's nominal values; different noise seeds); the first is fitted (`kukaid fit --robot`),
the second validates.  Prints, per base parameter, the estimate against the truth (relative
error, and in units of its standard deviation σ), the per-joint friction errors, the physical
consistency, and the per-axis relative error on the validation log.  "Well excited": σ under
0.5 % of the parameter.  Without --rotor the simulated robot has no rotor inertia (its torques
are the links' alone); with it the robot has one and the fit estimates it (--rotor-inertia).
``--kukaid`` names the kukaid command (default: this interpreter's kukaid_cli); `fit --robot`
comes from the robot-identification work (issue 15).  Prints; asserts nothing.
"""
from __future__ import annotations

import argparse
import json
import shlex
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

WELL = 0.005  # (corrected) relative standard deviation of a well-excited base parameter


def run(cmd: list[str], kukaid: list[str]) -> str:
    r = subprocess.run(kukaid + cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"failed: kukaid {' '.join(cmd)}\n{r.stderr.strip()}")
    return r.stdout


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=None, help="folder for the files (default: a temporary one)")
    ap.add_argument("--kukaid", default=f"{sys.executable} -m kukaid_cli.main")
    ap.add_argument("--fit-kukaid", default=None, help="kukaid command for fit and validate (default: --kukaid)")
    ap.add_argument("--robot", default="kr6-r700-sixx", help="bundled robot or URDF (six axes)")
    ap.add_argument("--rotor", action="store_true", help="simulate and fit rotor inertias")
    ap.add_argument("--coupled", action="store_true",
                    help="motor-side torques of drives with a coupled wrist (implies --rotor; fit with --torque-side "
                         "motor --coupling)")
    ap.add_argument("--repeat", type=int, default=6, help="periods of the fitted excitation (10 s each)")
    ap.add_argument("--cutoff", type=float, default=None, help="fit's --cutoff, Hz (default: the fit's default)")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    from kukaid.identify.robot_fit import well_excited
    from kukaid.logs import read_hdf5

    kk = shlex.split(a.kukaid)
    kf = shlex.split(a.fit_kukaid) if a.fit_kukaid else kk
    out = a.out or Path(tempfile.mkdtemp(prefix="kukaid_e2e_"))
    out.mkdir(parents=True, exist_ok=True)
    cfg = out / "sim.json"
    sim_cfg: dict = {"armature": bool(a.rotor or a.coupled)}
    fit_extra = ["--rotor-inertia"] if a.rotor or a.coupled else ["--no-rotor-inertia"]
    fit_extra += ["--cutoff", str(a.cutoff)] if a.cutoff is not None else []
    if a.coupled:
        C = np.zeros((6, 6))
        C[4, 3], C[5, 3], C[5, 4] = 0.2, -0.1, 0.15  # the A5 and A6 motors also turn with A4, A6's with A5
        sim_cfg.update(torque_side="motor", coupling=C.tolist())
        (out / "coupling.json").write_text(json.dumps(C.tolist()))
        fit_extra += ["--torque-side", "motor", "--coupling", str(out / "coupling.json")]
    cfg.write_text(json.dumps(sim_cfg))
    f = {k: str(out / k) for k in ("fit.json", "val.json", "fit.h5", "val.h5", "p.json")}
    run(["excite", "fourier", "--robot", a.robot, "-o", f["fit.json"], "--repeat", str(a.repeat)], kk)
    run(["excite", "fourier", "--robot", a.robot, "-o", f["val.json"], "--seed", "7", "--harmonics", "4",
         "--period", "8", "--repeat", "4"], kk)
    run(["capture", f["fit.json"], "-o", f["fit.h5"], "--seed", "1", "--sim-config", str(cfg), "--force"], kk)
    run(["capture", f["val.json"], "-o", f["val.h5"], "--seed", "2", "--sim-config", str(cfg), "--force"], kk)
    run(["fit", f["fit.h5"], "--robot", a.robot, "-o", f["p.json"]] + fit_extra, kf)
    val = json.loads(run(["validate", "--params", f["p.json"], f["val.h5"], "--json"], kf))
    p = json.loads(Path(f["p.json"]).read_text())
    tr = read_hdf5(f["fit.h5"]).attrs["truth"]
    pi = np.ravel(tr["pi"])
    bp = p["base_parameters"]
    ind, dep = np.asarray(bp["independent"], int), np.asarray(bp["dependent"], int)
    beta = pi[ind] + (np.asarray(bp["R"], float) @ pi[dep] if dep.size else 0.0)
    # a rotor that is one column with link inertias is folded into the least-squares base parameters
    rot = p["metrics"]["choices"].get("rotor") or {}
    rotor_true = np.asarray(tr["drive"]["rotor_inertia"], float)
    beta_ls = beta.copy()
    for name, into in zip(rot.get("folded") or [], rot.get("folded_into") or []):
        beta_ls = beta_ls + np.asarray(into, float) * rotor_true[int(name[1:]) - 1]
    sig = np.asarray(bp["sigma"], float)
    well = well_excited(p, WELL)
    res = {"folder": str(out), "base_parameters": len(beta), "well_excited": int(well.sum()),
           "physically_consistent": bool(p["metrics"].get("physically_consistent"))}
    for key, b in (("values", beta), ("least_squares", beta_ls)):
        est = np.asarray(bp[key], float)
        rel, z = np.abs(est - b) / np.abs(b), np.abs(est - b) / sig
        res[key] = {"max_rel_error_well": float(rel[well].max()), "median_rel_error_well": float(np.median(rel[well])),
                    "max_err_in_sigma_well": float(z[well].max()), "median_err_in_sigma_well": float(np.median(z[well])),
                    "within_2pct_well": int((rel[well] <= 0.02).sum())}
    fr = p["friction"]["values"]
    n = len(tr["offset"])
    fc = [abs(fr[f"A{j + 1}.Fc"] / tr["friction"]["Fc"][j] - 1) for j in range(n)]
    fv = [abs(fr[f"A{j + 1}.Fv"] / tr["friction"]["Fv"][j] - 1) for j in range(n)]
    res["friction"] = {"max_rel_error_Fc": max(fc), "max_rel_error_Fv": max(fv)}
    res["validation"] = {ax: v.get("rel_error", v.get("relative_error")) for ax, v in val["axes"].items()}
    res["validation_mean"] = val["mean_relative_error"]
    if a.json:
        print(json.dumps(res))
        return
    print(f"files in {out}")
    print(f"{len(beta)} base parameters, {int(well.sum())} well excited (sigma < {100 * WELL:g} %); "
          f"physically consistent: {res['physically_consistent']}")
    print(f"{'estimate':<15}{'max rel err':>12}{'median':>9}{'max |err|/σ':>13}{'median':>9}{'within 2 %':>12}")
    for key in ("values", "least_squares"):
        r = res[key]
        print(f"{key:<15}{100 * r['max_rel_error_well']:>11.2f}%{100 * r['median_rel_error_well']:>8.2f}%"
              f"{r['max_err_in_sigma_well']:>13.2f}{r['median_err_in_sigma_well']:>9.2f}"
              f"{r['within_2pct_well']:>7d} of {int(well.sum())}")
    print(f"friction: max relative error Fc {100 * res['friction']['max_rel_error_Fc']:.2f} %, "
          f"Fv {100 * res['friction']['max_rel_error_Fv']:.2f} %")
    print("validation (second trajectory, other noise): " + ", ".join(f"{k} {100 * v:.1f} %" for k, v in
                                                                        res["validation"].items())
          + f"; mean {100 * res['validation_mean']:.1f} %")


if __name__ == "__main__":
    main()
