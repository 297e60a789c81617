"""Heavy-robot check: does `kukaid fit --robot` with its defaults beat the maker's nominal model on
a robot it was not tuned on?

The robot: the bundled KR 6 R700 sixx scaled to a heavy KUKA (lengths x3, masses x40: about 1 t
moving, efforts x120, speeds x0.35), simulated on the six-axis virtual KR C4 with a *truth* away
from the URDF the fit is given: every link perturbed (``perturb``), systematic mass errors of the
nominal URDF (-25 % to +30 % per link, its inertias and first moments scaled alike) and a gas
counterbalance on A2 that the URDF does not know (a cylinder between the column and the link arm,
force from the gas law, torque from the geometry: nonlinear in q2). Each recording is a Fourier
excitation of all six axes (its own seed) followed by a rest (``--rest`` s: the standstill rows).

Three recordings per robot seed: fit on each, validate on the other two pooled, mean over the
three; for

- ``defaults``: ``fit_robot`` with its default settings;
- ``nominal+friction``: the nominal URDF's rigid body + per-joint Coulomb, viscous and offset by
  least squares on the fit recording (the maker's model with friction);
- ``naive``: ordinary least squares of the base regressor + Coulomb, viscous, offset.

Prints a table per model (per-joint held-out relative error, mean) and the fitted link masses as
multiples of the nominal ones (the issue's plausibility range: 0.4-2.5x). ``--json`` for a machine.
``--quick``: one robot seed, 4 s recordings (what the test suite runs).

Run: python benchmarks/robot_heavy_check.py [--seeds 0 1] [--duration 10] [--rest 1.5] [--json] [--quick]
"""
from __future__ import annotations

import argparse
import json
import math
import re
import sys
import tempfile
from pathlib import Path

import numpy as np

LENGTH, MASS, EFFORT, SPEED = 3.0, 40.0, 120.0, 0.35
#: the nominal URDF's mass errors per link (the truth is the URDF's masses times these, perturbed)
MASS_ERROR = (1.2, 0.75, 1.3, 0.8, 1.25, 0.85)


def heavy_urdf(out: Path, mass_error=None) -> Path:
    """The KR 6 R700 sixx URDF scaled to a heavy robot (``mass_error``: per-link mass factors)."""
    from kukaid.models.urdf import robot_urdf

    text = robot_urdf("kr6-r700-sixx").read_text()
    text = re.sub(r"<!--.*?-->", "", text, flags=re.S)
    me = list(mass_error or [1.0] * 6)

    def link(mo: re.Match) -> str:
        body = mo.group(0)
        name = mo.group(1)
        k = int(name.split("_")[1]) - 1 if name.startswith("link_") else None
        f = MASS * (me[k] if k is not None else 1.0)
        body = re.sub(r'<origin xyz="([^"]+)"', lambda m: '<origin xyz="%s"' % " ".join(
            f"{LENGTH * float(x):.6g}" for x in m.group(1).split()), body)
        body = re.sub(r'<mass value="([^"]+)"', lambda m: f'<mass value="{f * float(m.group(1)):.6g}"', body)
        body = re.sub(r'(i[xyz]{2})="([^"]+)"', lambda m: f'{m.group(1)}="{f * LENGTH ** 2 * float(m.group(2)):.6g}"',
                      body)
        return body

    text = re.sub(r'<link name="([^"]+)">.*?</link>', link, text, flags=re.S)

    def joint(mo: re.Match) -> str:
        body = mo.group(0)
        body = re.sub(r'<origin xyz="([^"]+)"', lambda m: '<origin xyz="%s"' % " ".join(
            f"{LENGTH * float(x):.6g}" for x in m.group(1).split()), body)
        body = re.sub(r'velocity="([^"]+)"', lambda m: f'velocity="{SPEED * float(m.group(1)):.6g}"', body)
        body = re.sub(r'effort="([^"]+)"', lambda m: f'effort="{EFFORT * float(m.group(1)):.6g}"', body)
        return body

    text = re.sub(r'<joint name="[^"]+" type="revolute">.*?</joint>', joint, text, flags=re.S)
    text = text.replace('<robot name="kr6_r700_sixx">', '<robot name="heavy_sixx">')
    out.write_text(text)
    return out


class Counterbalance:
    """A gas spring between the column and the link arm, acting on A2 (N·m; external torque of the
    simulator, so the measured motor torque is reduced by it).

    Cylinder from a point ``a`` m from the A2 axis on the column to a point ``b`` m out on the arm
    (angle ``q2 - q0`` between them); gas force ``F0 (s0 / s)^kappa`` with ``s`` the cylinder's
    length; torque ``F a b sin(q2 - q0) / s``, signed to hold the arm up."""

    def __init__(self, F0: float, a: float = 0.45, b: float = 0.9, q0: float = -math.pi / 2, kappa: float = 1.3,
                 sign: float = 1.0) -> None:
        self.F0, self.a, self.b, self.q0, self.kappa, self.sign = F0, a, b, q0, kappa, sign
        self.s0 = math.hypot(a, b)

    def torque(self, q2):
        x = np.asarray(q2, float) - self.q0 + math.pi / 2
        s = np.sqrt(self.a ** 2 + self.b ** 2 - 2 * self.a * self.b * np.cos(x))
        return self.sign * self.F0 * (self.s0 / s) ** self.kappa * self.a * self.b * np.sin(x) / s

    def __call__(self, t, q, qd):
        out = np.zeros(6)
        out[1] = self.torque(q[1])
        return out


def recordings(urdf_true: Path, seed: int, duration: float, rest: float, n: int = 3):
    """``n`` simulated recordings of the heavy robot (truth seed ``seed``), with a counterbalance."""
    from kukaid.excite.fourier import fourier
    from kukaid.models.robot import RobotModel
    from kukaid.sim.robot_plant import RobotSimConfig, VirtualRobotKRC4

    robot = RobotModel(urdf_true)
    # the counterbalance carries about half of A2's largest gravity torque over its range
    qs = np.zeros((41, 6))
    qs[:, 1] = np.linspace(max(robot.lower[1], -2.6), min(robot.upper[1], 0.5), 41)
    g2 = robot.rnea(qs, np.zeros_like(qs), np.zeros_like(qs))[:, 1]
    cb = Counterbalance(1.0)
    c1 = cb.torque(qs[:, 1])
    cb.sign = float(np.sign(np.mean(g2 * c1)) or 1.0)
    cb.F0 = 0.5 * np.abs(g2).max() / np.abs(c1).max()
    cfg = RobotSimConfig(robot=str(urdf_true), truth_seed=seed, perturb=0.15, noise_rel=0.002)
    logs = []
    for k in range(n):
        period = duration / 2.0
        traj = fourier(str(urdf_true), harmonics=4, period=period, periods=2, seed=100 * seed + k + 1,
                       iterations=0, starts=2, span=0.6)
        sim = VirtualRobotKRC4(cfg, seed=1000 * seed + k)
        sim.set_external_torque(cb)
        logs.append(sim.run(traj, settle=rest))
    return logs, cb


def nominal_friction_fit(robot, fit_log, val_logs):
    """The nominal URDF's rigid body + per-joint Coulomb, viscous, offset by least squares."""
    from kukaid.identify.robot_fit import RobotFitSettings, _cutoff, motion

    s = RobotFitSettings(v_smooth=0.0)
    m = motion(fit_log, robot.n, s)
    fs = 1.0 / fit_log.sample_time
    e = int(math.ceil(2.0 * fs / _cutoff(s, fs)))
    r = m.tau - robot.rnea(m.q, m.qd, m.qdd)
    coef = []
    for j in range(robot.n):
        A = np.column_stack([np.sign(m.qd[e:-e, j]), m.qd[e:-e, j], np.ones(m.q.shape[0] - 2 * e)])
        coef.append(np.linalg.lstsq(A, r[e:-e, j], rcond=None)[0])
    return _pooled(robot, val_logs, s, lambda mv: robot.rnea(mv.q, mv.qd, mv.qdd) + np.column_stack(
        [c[0] * np.sign(mv.qd[:, j]) + c[1] * mv.qd[:, j] + c[2] for j, c in enumerate(coef)]))


def naive_fit(robot, fit_log, val_logs):
    from kukaid.diagnose.validate import validate
    from kukaid.identify.fitted import RobotFile
    from kukaid.identify.robot_fit import RobotFitSettings, fit_robot

    p = fit_robot([fit_log], robot, RobotFitSettings(consistent=False, spring=False, ripple=0, v_smooth=0.0, deadband=0.0,
                                                     choose=False, mass_bounds=None, total_mass_bounds=None,
                                                     weighting="none", reversal_window=0.0, rotor=False,
                                                     viscous_beyond="linear"))
    p["base_parameters"]["values"] = p["base_parameters"]["least_squares"]
    p["friction"]["values"] = p["friction"]["least_squares"]
    return _rel(validate(RobotFile(p, robot=robot), val_logs))


def _pooled(robot, logs, s, predict):
    from kukaid.identify.robot_fit import _cutoff, motion

    num, den = np.zeros(robot.n), np.zeros(robot.n)
    for lg in logs:
        mv = motion(lg, robot.n, s, filter_tau=False)
        fs = 1.0 / lg.sample_time
        e = int(math.ceil(2.0 * fs / _cutoff(s, fs)))
        t, th = lg.tau[e:-e], predict(mv)[e:-e]
        num += np.sum((t - th) ** 2, axis=0)
        den += np.sum(t ** 2, axis=0)
    return np.sqrt(num / den).tolist()


def _rel(scores):
    return [scores[j].rel_error for j in sorted(scores)]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="*", default=[0, 1])
    ap.add_argument("--duration", type=float, default=10.0, help="s of excitation per recording")
    ap.add_argument("--rest", type=float, default=1.5, help="s at rest after each excitation")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--quick", action="store_true", help="one seed, 4 s recordings (the test suite's size)")
    ap.add_argument("--settings", default="{}", help="JSON of RobotFitSettings fields for the 'defaults' row "
                                                     "(to compare a variant), e.g. '{\"prior_weight\": 0.01}'")
    a = ap.parse_args()
    if a.quick:
        a.seeds, a.duration, a.rest = [0], 4.0, 0.5

    from kukaid.diagnose.validate import validate
    from kukaid.identify.fitted import RobotFile
    from kukaid.identify.robot_fit import RobotFitSettings, fit_robot
    from kukaid.models.robot import RobotModel

    settings = RobotFitSettings(**json.loads(a.settings))

    scratch = tempfile.TemporaryDirectory(prefix="kukaid_heavy_")  # removed at exit (each test-suite run made one)
    tmp = Path(scratch.name)
    urdf_nominal = heavy_urdf(tmp / "heavy_nominal.urdf")
    urdf_true = heavy_urdf(tmp / "heavy_true.urdf", [1.0 / f for f in MASS_ERROR])   # nominal = truth x error
    nominal = RobotModel(urdf_nominal)
    m0 = nominal.pi_nominal[0::10]
    models = {"defaults": [], "nominal+friction": [], "naive": []}
    masses = []
    released = []
    cutoffs = []
    rest_share = []
    for seed in a.seeds:
        logs, cb = recordings(urdf_true, seed, a.duration, a.rest)
        for k, fit_log in enumerate(logs):
            val = [lg for i, lg in enumerate(logs) if i != k]
            p = fit_robot([fit_log], nominal, settings)
            models["defaults"].append(_rel(validate(RobotFile(p, robot=nominal), val)))
            sp = p["standard_parameters"]
            masses.append([sp[lk]["m"] / m for lk, m in zip(nominal.link_names, m0)])
            released.append(bool((p["metrics"]["choices"].get("mass_bounds") or {}).get("released")))
            cutoffs.append(p["metrics"]["choices"]["cutoff"]["chosen"])
            models["nominal+friction"].append(nominal_friction_fit(nominal, fit_log, val))
            models["naive"].append(naive_fit(nominal, fit_log, val))
            qd = np.gradient(fit_log.q, fit_log.time, axis=0)
            rest_share.append(float(np.mean(np.all(np.abs(qd) < 1e-3, axis=1))))
    rows = {name: {"per_joint": np.mean(v, axis=0).tolist(), "mean": float(np.mean(v))} for name, v in models.items()}
    out = {"settings": json.loads(a.settings), "seeds": a.seeds, "duration_s": a.duration, "rest_s": a.rest, "models": rows,
           "mass_ratio": {"min": float(np.min(masses)), "max": float(np.max(masses)),
                          "per_fit": np.round(masses, 3).tolist(), "bounds_released": int(sum(released))},
           "rest_share": float(np.mean(rest_share)), "cutoff_hz": cutoffs,
           "counterbalance_peak_Nm": float(np.abs(cb.torque(np.linspace(-2.6, 0.5, 50))).max())}
    if a.json:
        print(json.dumps(out, indent=1))
        return 0
    print(f"heavy robot (KR 6 R700 sixx x{LENGTH:g} lengths, x{MASS:g} masses; nominal mass errors {MASS_ERROR}; "
          f"A2 counterbalance up to {out['counterbalance_peak_Nm']:.0f} N·m), seeds {a.seeds}, "
          f"{a.duration:g} s + {a.rest:g} s rest per recording ({100 * out['rest_share']:.0f} % of rows at rest)")
    print("held-out relative error (fit on one recording, validate on the other two, mean over fits):")
    print(f"{'model':<18}" + "".join(f"{f'A{j}':>7}" for j in range(1, 7)) + f"{'mean':>8}")
    for name, r in rows.items():
        print(f"{name:<18}" + "".join(f"{100 * x:6.1f}%" for x in r["per_joint"]) + f"{100 * r['mean']:7.1f}%")
    print(f"fitted link masses / nominal (defaults): {out['mass_ratio']['min']:.2f} to {out['mass_ratio']['max']:.2f}"
          f" (plausible: 0.4-2.5); bounds released by held-out error in {out['mass_ratio']['bounds_released']} of "
          f"{len(released)} fits")
    print(f"low-pass cut-off of the defaults' fits, Hz: {' '.join(f'{c:g}' for c in cutoffs)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
