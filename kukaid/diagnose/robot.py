"""Diagnose a robot parameter file (``kukaid.robot_params/1``): which effect a URDF cannot say do
the logs show, on which joints, and does adding it predict recordings its fit did not see better.

The file's rigid body (its base parameters) stays as fitted; each joint's own terms (friction,
offset, spring, ripple, as the file has them) are refitted together with a candidate's columns on
the training folds (each log left out in turn, else :data:`FOLDS` contiguous blocks) and judged on
the held-out fold, every sample of it, as the one-axis diagnose judges its candidates.

Candidates:

- ``counterbalance@A<j>``: a gas (or hydraulic) spring balancing joint j's gravity, one per joint
  that carries gravity: a cylinder from the column to the arm, force from the gas law
  ``F0 (s0 / s)^kappa``, torque ``F a b sin(q - q0) / s`` with ``s`` the cylinder length; its
  attachment angle ``q0`` and lever ratio ``a / b`` from a small grid (chosen on the training
  folds), its force ``F0`` by least squares. Nonlinear in q, so the joint's spring ``k q`` and
  offset do not hold it over the whole range.
- ``payload``: a mass at the flange other than the URDF's: the last link's mass and first
  moments change (``m``, ``m c``: 4 columns of the joint-torque regressor, shared by every joint),
  by least squares; plausible when the mass change is within the robot's total mass.

A counterbalance is a candidate on the joints that carry at least half of the largest gravity
torque range, and plausible when its torque reaches :data:`MIN_CB_SHARE` of its joint's largest
gravity torque over the data (with the joint's spring and offset refitted beside it, its own
torque may exceed the gravity it balances). The gas spring's geometry is chosen on all samples (one shape per joint); its force scale
and the joint's own terms are fitted on the training folds only.

A candidate is named when it lowers the held-out relative error of the joints it acts on by more
than :data:`MARGIN` and makes no joint's held-out error worse by as much; the best is added
and the others tried again (at most ``max_steps``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from kukaid.errors import KukaidError

#: a candidate must lower the held-out relative error of the joints it acts on by this share
MARGIN = 0.05
#: a counterbalance carries a real share of its joint's gravity torque (half its range): at least this
MIN_CB_SHARE = 0.1
#: contiguous blocks of one recording when there is only one
FOLDS = 5
#: gas-spring geometry grid: attachment angles (rad) and lever ratios a / b; polytropic exponent
CB_ANGLES = np.linspace(-math.pi, math.pi, 25)[:-1]
CB_RATIOS = (0.3, 0.5, 0.7)
CB_KAPPA = 1.3


def gas_spring(q: np.ndarray, q0: float, ratio: float, kappa: float = CB_KAPPA) -> np.ndarray:
    """Torque shape of a gas spring (per unit force scale, lever b = 1 m, a = ratio), N·m per N."""
    x = np.asarray(q, float) - q0
    a, b = ratio, 1.0
    s = np.sqrt(a * a + b * b - 2 * a * b * np.cos(x))
    s0 = math.hypot(a, b)
    return (s0 / np.maximum(s, 1e-9)) ** kappa * a * b * np.sin(x) / np.maximum(s, 1e-9)


@dataclass
class RobotDiagnosis:
    """Result of :func:`diagnose_robot`: ``lines()`` for the terminal, ``to_json()`` for a machine."""

    axes: list[int]
    folds: str
    before: list[float]                    # held-out relative error per joint, the file's terms refitted
    after: list[float]
    steps: list[dict] = field(default_factory=list)
    rejected: list[dict] = field(default_factory=list)
    in_sample: list[float] = field(default_factory=list)   # the file as it is, relative error per joint

    def to_json(self) -> dict[str, Any]:
        return {"schema": "kukaid.robot_diagnosis/1", "axes": self.axes, "folds": self.folds,
                "relative_error_given": self.in_sample, "heldout_relative_error_before": self.before,
                "heldout_relative_error_after": self.after, "steps": self.steps, "rejected": self.rejected}

    def lines(self) -> list[str]:
        ax = " ".join(f"{f'A{a}':>7}" for a in self.axes)
        out = [f"robot diagnosis, held out: {self.folds}",
               f"{'relative error':<34}{ax}",
               f"{'  the file as it is':<34}" + " ".join(f"{100 * x:6.1f}%" for x in self.in_sample),
               f"{'  held out, its terms refitted':<34}" + " ".join(f"{100 * x:6.1f}%" for x in self.before)]
        for k, st in enumerate(self.steps, 1):
            label = "  + " + st["name"]
            out.append(f"{label:<34}" + " ".join(f"{100 * x:6.1f}%" for x in st["heldout_after"]))
        if self.steps:
            for k, st in enumerate(self.steps, 1):
                par = ", ".join(f"{k2} {v:.4g}" for k2, v in st["params"].items())
                out.append(f"step {k}: {st['name']} ({par}): held-out error of {', '.join(st['joints'])} "
                           f"{100 * st['mean_before']:.1f} -> {100 * st['mean_after']:.1f} %")
        else:
            out.append("no effect named: none lowers the held-out error enough")
        for r in self.rejected:
            out.append(f"not named: {r['name']}: {r['reason']}")
        return out


def _signals(params: dict, logs: Sequence[Any], robot):
    """The fit's samples of the logs (filtered, trimmed, decimated), the file's prediction at them and
    each joint's own columns (as the file has them)."""
    from kukaid.identify.robot_fit import (DriveModel, RobotFitSettings, _blocks, _samples, extra_names, extras)

    s = params["settings"]
    settings = RobotFitSettings(**{"ripple": 0, **{k: s[k] for k in RobotFitSettings.__dataclass_fields__ if k in s}})
    if settings.torque_side != "joint" or settings.rotor:
        raise KukaidError("diagnose: robot parameter files with motor-side torques or rotor inertias are not "
                          "supported yet (fit with joint-side torques)")
    n = robot.n
    drive = DriveModel.direct(n)
    m = _samples(logs, n, settings, drive)
    names = extra_names(robot, settings)
    fr = params["friction"]
    x = np.array([fr["values"].get(k, 0.0) for k in names])
    bp = params["base_parameters"]
    ind, beta = np.asarray(bp["independent"], int), np.asarray(bp["values"], float)
    N = m.q.shape[0]
    rigid = np.empty((N, n))
    # each joint's own terms as the file has them: ripple harmonics the fit held at 0 (not covered by
    # its range, or not chosen) stay out, else their refit bends the torque outside the fitted range
    own = [[i for i, nm in enumerate(names) if nm.startswith(f"A{j + 1}.") and not (".ripple_" in nm and x[i] == 0.0)]
           for j in range(n)]
    Fj = [np.empty((N, len(c))) for c in own]
    payload = np.empty((N, n, 4))
    k0 = robot.n_std - 10
    for rows, mb in _blocks(m):
        Y = robot.regressor(mb.q, mb.qd, mb.qdd)
        F = extras(robot, mb, settings, drive, qd_range=fr.get("qd_range"))
        rigid[rows] = Y[:, :, ind] @ beta
        payload[rows] = Y[:, :, k0: k0 + 4]
        for j in range(n):
            Fj[j][rows] = F[:, j, own[j]]
    tau_hat = rigid + np.column_stack([Fj[j] @ x[own[j]] for j in range(n)])
    return m, rigid, Fj, payload, tau_hat


def _design(Fj, extra_cols, j):
    cols = [Fj[j]] + ([extra_cols[j]] if extra_cols is not None else [])
    A = np.concatenate(cols, axis=1)
    live = np.any(A != 0, axis=0)
    return A, live


def _heldout(r: np.ndarray, tau: np.ndarray, Fj: list, shared: list | None, local: dict | None, folds: np.ndarray,
             K: int, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Held-out relative error per joint of ``r = tau - rigid`` explained by each joint's own columns
    ``Fj`` plus ``local`` {joint: (N, c) columns of that joint only} plus ``shared`` (per joint
    (N, s) columns whose coefficients all joints share), fitted on the other folds (weights ``w``
    per joint). Returns the errors (n,) and the coefficients fitted on all samples."""
    n = r.shape[1]
    ks = [F.shape[1] + (local[j].shape[1] if local and j in local else 0) for j, F in enumerate(Fj)]
    ns = 0 if shared is None else shared[0].shape[1]
    off = np.concatenate([[0], np.cumsum(ks)])
    P = int(off[-1]) + ns

    def cols(j, rows):
        parts = [Fj[j][rows]]
        if local and j in local:
            parts.append(local[j][rows])
        return np.concatenate(parts, axis=1)

    def normal(rows):
        A, b = np.zeros((P, P)), np.zeros(P)
        for j in range(n):
            D = cols(j, rows)
            idx = np.arange(off[j], off[j + 1])
            A[np.ix_(idx, idx)] += w[j] * D.T @ D
            b[idx] += w[j] * D.T @ r[rows, j]
            if shared is not None:
                S = shared[j][rows]
                si = np.arange(off[-1], P)
                A[np.ix_(idx, si)] += w[j] * D.T @ S
                A[np.ix_(si, idx)] += w[j] * S.T @ D
                A[np.ix_(si, si)] += w[j] * S.T @ S
                b[si] += w[j] * S.T @ r[rows, j]
        return A, b

    def solve(A, b):
        dg = np.diag(A)
        live = dg > 1e-300
        x = np.zeros(P)
        d = 1.0 / np.sqrt(dg[live])
        x[live] = d * np.linalg.lstsq(d[:, None] * A[np.ix_(live, live)] * d[None, :], d * b[live], rcond=1e-12)[0]
        return x

    parts = [normal(folds == f) for f in range(K)]
    num, den = np.zeros(n), np.zeros(n)
    for f in range(K):
        A = sum(p[0] for p in parts) - parts[f][0]
        b = sum(p[1] for p in parts) - parts[f][1]
        x = solve(A, b)
        rows = folds == f
        for j in range(n):
            pred = cols(j, rows) @ x[off[j]:off[j + 1]]
            if shared is not None:
                pred = pred + shared[j][rows] @ x[off[-1]:]
            num[j] += float(np.sum((r[rows, j] - pred) ** 2))
            den[j] += float(np.sum(tau[rows, j] ** 2))
    x_all = solve(sum(p[0] for p in parts), sum(p[1] for p in parts))
    return np.sqrt(num / np.maximum(den, 1e-300)), x_all


def diagnose_robot(params: dict, logs: Sequence[Any], robot=None, *, max_steps: int = 3) -> RobotDiagnosis:
    """Find the effects of :mod:`this module`'s candidates that the logs show and the robot file
    misses (see the module's text). ``params``: a validated ``kukaid.robot_params/1`` dictionary."""
    from kukaid.identify.robot_fit import _folds
    from kukaid.models.robot import RobotModel

    robot = robot or RobotModel(params["robot"]["urdf"])
    sha = params["robot"].get("sha256")
    if sha and sha != robot.sha256:
        raise KukaidError(f"{robot.path}: this URDF is not the one the parameters were fitted with")
    if not logs:
        raise KukaidError("diagnose: no logs")
    m, rigid, Fj, payload, tau_hat = _signals(params, logs, robot)
    n = robot.n
    axes = list(range(1, n + 1))
    tau = m.tau
    r = tau - rigid
    folds, K, how = _folds(m, logs)
    in_sample = (np.linalg.norm(tau - tau_hat, axis=0) / np.maximum(np.linalg.norm(tau, axis=0), 1e-300)).tolist()
    sig = np.maximum(np.std(tau - tau_hat, axis=0), 1e-9)
    w = 1.0 / sig ** 2
    # joints that carry gravity over the data: a counterbalance candidate each
    g = robot.rnea(m.q[::10], np.zeros_like(m.q[::10]), np.zeros_like(m.q[::10]))
    # (a counterbalance sits on a joint that carries the most gravity: at least half the largest range)
    span = np.ptp(g, axis=0)
    grav = [j for j in range(n) if span[j] >= 0.5 * span.max() and np.std(g[:, j]) > 0.1 * np.sqrt(np.mean(tau[:, j] ** 2))]
    cands: dict[str, dict] = {}
    for j in grav:
        cands[f"counterbalance@A{j + 1}"] = {"joint": j}
    cands["payload"] = {"shared": [payload[:, j, :] for j in range(n)]}
    local: dict = {}
    shared = None
    err, _ = _heldout(r, tau, Fj, shared, local, folds, K, w)
    before = err.copy()
    steps, rejected = [], []
    remaining = dict(cands)
    for _ in range(max(0, max_steps)):
        best = None
        for name, c in remaining.items():
            if "joint" in c:
                j = c["joint"]
                # the geometry from the grid, on all samples of the training data alike (a shape, one scale)
                q = m.q[:, j]
                score, shape, geo = np.inf, None, None
                A0 = Fj[j]
                for q0 in CB_ANGLES:
                    for rho in CB_RATIOS:
                        col = gas_spring(q, q0, rho)[:, None]
                        D = np.concatenate([A0, col], axis=1)
                        coef = np.linalg.lstsq(D, r[:, j], rcond=None)[0]
                        res = float(np.sum((r[:, j] - D @ coef) ** 2))
                        if res < score:
                            score, shape, geo = res, col, (float(q0), float(rho))
                trial_local = {**local, j: np.concatenate([local[j], shape], axis=1) if j in local else shape}
                e, x = _heldout(r, tau, Fj, shared, trial_local, folds, K, w)
                joints = [j]
                kx = Fj[j].shape[1] + (local[j].shape[1] if j in local else 0)
                off_j = sum(F.shape[1] + (local[i].shape[1] if i in local else 0) for i, F in enumerate(Fj[:j]))
                scale = float(x[off_j + kx])
                peak = float(np.max(np.abs(scale * shape)))
                info = {"q0_rad": geo[0], "lever_ratio": geo[1], "peak_torque_Nm": peak,
                        "share_of_gravity": peak / max(float(np.max(np.abs(g[:, j]))), 1e-12)}
            else:
                trial_shared = c["shared"] if shared is None else [np.concatenate([a, b], axis=1)
                                                                   for a, b in zip(shared, c["shared"])]
                e, x = _heldout(r, tau, Fj, trial_shared, local, folds, K, w)
                joints = list(range(n))
                dm = float(x[-4])
                info = {"mass_kg": dm, "first_moment_kgm": [float(v) for v in x[-3:]]}
            mb, ma = float(np.mean(err[joints])), float(np.mean(e[joints]))
            worse = [f"A{k + 1}" for k in range(n) if e[k] > (1 + MARGIN) * err[k] + 1e-12]
            reason = None
            if ma > (1 - MARGIN) * mb:
                reason = f"held-out error {100 * mb:.2f} -> {100 * ma:.2f} % (needs a {100 * MARGIN:.0f} % drop)"
            elif worse:
                reason = f"makes {', '.join(worse)} worse on held-out data"
            elif "joint" in c and info["share_of_gravity"] < MIN_CB_SHARE:
                reason = (f"implausible for a counterbalance: {info['peak_torque_Nm']:.3g} N·m, "
                          f"{100 * info['share_of_gravity']:.0f} % of the joint's gravity torque")
            elif name == "payload" and not (abs(info["mass_kg"]) < float(np.sum(np.maximum(robot.pi_nominal[0::10], 0)))):
                reason = f"implausible mass change {info['mass_kg']:.3g} kg"
            if reason is None and (best is None or (mb - ma) / mb > best[0]):
                best = ((mb - ma) / mb, name, e, joints, info, mb, ma)
            elif reason is not None:
                rejected_now = {"name": name, "reason": reason}
                rejected = [x_ for x_ in rejected if x_["name"] != name] + [rejected_now]
        if best is None:
            break
        _, name, e, joints, info, mb, ma = best
        c = remaining.pop(name)
        rejected = [x_ for x_ in rejected if x_["name"] != name]
        if "joint" in c:
            j = c["joint"]
            col = gas_spring(m.q[:, j], info["q0_rad"], info["lever_ratio"])[:, None]
            local = {**local, j: np.concatenate([local[j], col], axis=1) if j in local else col}
        else:
            shared = c["shared"] if shared is None else [np.concatenate([a, b], axis=1) for a, b in zip(shared, c["shared"])]
        steps.append({"name": name, "joints": [f"A{k + 1}" for k in joints], "params": {
            k: v for k, v in info.items() if not isinstance(v, list)}, "details": info,
            "mean_before": mb, "mean_after": ma, "heldout_before": err.tolist(), "heldout_after": e.tolist()})
        err = e
    return RobotDiagnosis(axes=axes, folds=how, before=before.tolist(), after=err.tolist(), steps=steps,
                          rejected=rejected, in_sample=in_sample)
