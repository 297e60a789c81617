"""Diagnose a robot parameter file (``kukaid.robot_params/1``): which effect a URDF cannot say do
the logs show, on which joints, and does adding it predict recordings its fit did not see better.

The file's rigid body (its base parameters) stays as fitted; each joint's own terms (friction,
offset, spring, ripple, as the file has them) are refitted together with a candidate's columns on
the training folds (each log left out in turn, else :data:`FOLDS` contiguous blocks) and judged on
the held-out fold, every sample of it, as the one-axis diagnose judges its candidates.

Candidates (:mod:`kukaid.diagnose.robot_candidates`): ``counterbalance@A<j>`` (a gas spring, on
the joints that carry at least half of the largest gravity torque range), ``payload`` (the last
link's mass and first moments), and per joint ``load_dependent_friction@A<j>``,
``thermal_friction@A<j>`` (with a temperature channel) and ``position_ripple@A<j>``.

A candidate's nonlinear settings (the ripple order, the load or the thermal form) are chosen on
the training folds only, by least squares of the joint's own terms with the candidate, so the
held-out fold judges the choice too (a search over many orders cannot fit the held-out data by
choosing); the gas spring's geometry is still chosen on all samples (see
:class:`~kukaid.diagnose.robot_candidates.Counterbalance`). Its coefficients and the joint's terms
are then fitted on the training folds and the held-out error measured. Recordings the file was
fitted on are not used when at least two others remain (:func:`_unseen`).

A candidate is named when it lowers the held-out relative error of the joints it acts on by more
than :data:`MARGIN`, makes no joint's held-out error worse by as much, its gain is at least
:data:`MIN_T` standard errors of its spread over blocks of the held-out recordings, and its refit
on all samples passes its plausibility rule; the best is added and the others tried again (at most
``max_steps``). The noise floor per joint (:func:`kukaid.diagnose.noise.filtered_noise_floor`:
the RMSE of a perfect model in the fit's filtered comparison) is reported beside the errors.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from kukaid.diagnose.robot_candidates import (CB_ANGLES, CB_KAPPA, CB_RATIOS, MIN_CB_SHARE,  # noqa: F401
                                              Context, RobotCandidate, gas_spring, robot_candidates)
from kukaid.errors import KukaidError

#: a candidate must lower the held-out relative error of the joints it acts on by this share
MARGIN = 0.05
#: contiguous blocks of one recording when there is only one (and of each held-out recording, for the
#: spread of a candidate's held-out gain)
FOLDS = 5
#: a candidate's held-out gain must be at least this many standard errors of its spread over the
#: held-out blocks (about a 5 % one-sided chance that a candidate with no gain passes)
MIN_T = 2.0


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
    noise_floor: list[float] = field(default_factory=list)  # N·m per joint: the RMSE of a perfect model
    rms: list[float] = field(default_factory=list)          # N·m per joint: RMS of the compared torque
    tried: list[dict] = field(default_factory=list)         # every candidate of the first round, its evidence
    fitted_on: list[str] = field(default_factory=list)      # recordings the file was fitted on: not used

    @property
    def names(self) -> list[str]:
        return [s["name"] for s in self.steps]

    def rmse(self, rel: Sequence[float]) -> np.ndarray:
        """Relative errors per joint -> RMSE per joint, N·m."""
        return np.asarray(rel, float) * np.asarray(self.rms, float)

    def to_json(self) -> dict[str, Any]:
        return {"schema": "kukaid.robot_diagnosis/1", "axes": self.axes, "folds": self.folds,
                "relative_error_given": self.in_sample, "heldout_relative_error_before": self.before,
                "heldout_relative_error_after": self.after, "noise_floor_Nm": self.noise_floor,
                "heldout_rmse_before_Nm": self.rmse(self.before).tolist() if self.rms else [],
                "heldout_rmse_after_Nm": self.rmse(self.after).tolist() if self.rms else [],
                "steps": self.steps, "rejected": self.rejected, "tried": self.tried,
                "not_used_fitted_on": self.fitted_on}

    def lines(self) -> list[str]:
        ax = " ".join(f"{f'A{a}':>7}" for a in self.axes)
        out = [f"robot diagnosis, held out: {self.folds}"]
        if self.fitted_on:
            out.append(f"  not used: {', '.join(self.fitted_on)} (the file was fitted on it: its error is in-sample)")
        out += [f"{'relative error':<34}{ax}",
                f"{'  the file as it is':<34}" + " ".join(f"{100 * x:6.1f}%" for x in self.in_sample),
                f"{'  held out, its terms refitted':<34}" + " ".join(f"{100 * x:6.1f}%" for x in self.before)]
        for k, st in enumerate(self.steps, 1):
            label = "  + " + st["name"]
            out.append(f"{label:<34}" + " ".join(f"{100 * x:6.1f}%" for x in st["heldout_after"]))
        if self.noise_floor and self.rms:
            fl = np.asarray(self.noise_floor) / np.maximum(np.asarray(self.rms), 1e-300)
            out.append(f"{'  noise floor (a perfect model)':<34}" + " ".join(f"{100 * x:6.1f}%" for x in fl))
        if self.steps:
            for k, st in enumerate(self.steps, 1):
                par = ", ".join(f"{k2} {v:.4g}" if isinstance(v, float) else f"{k2} {v}" for k2, v in st["params"].items())
                out.append(f"step {k}: {st['name']} ({par}): held-out error of {', '.join(st['joints'])} "
                           f"{100 * st['mean_before']:.1f} -> {100 * st['mean_after']:.1f} %")
        else:
            out.append("no effect named: none lowers the held-out error enough")
        for r in self.rejected:
            out.append(f"not named: {r['name']}: {r['reason']}")
        return out


def _signals(params: dict, logs: Sequence[Any], robot):
    """The fit's samples of the logs (filtered, trimmed, decimated), the file's rigid-body torque,
    each joint's own columns (as the file has them), the file's prediction and the candidates'
    :class:`Context`."""
    from kukaid.identify.robot_fit import (DriveModel, RobotFitSettings, _blocks, _cutoff, _samples, extra_names,
                                           extras, sample_rows)

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
    rigid, gravity, friction = np.empty((N, n)), np.empty((N, n)), np.zeros((N, n))
    sign = np.zeros((N, n))
    # each joint's own terms as the file has them: ripple harmonics the fit held at 0 (not covered by
    # its range, or not chosen) stay out, else their refit bends the torque outside the fitted range
    own = [[i for i, nm in enumerate(names) if nm.startswith(f"A{j + 1}.") and not (".ripple_" in nm and x[i] == 0.0)]
           for j in range(n)]
    fric = [[i for i, nm in enumerate(names) if nm.split(".", 1)[1] in ("Fc", "Fv", "Fs-Fc") and nm.startswith(f"A{j + 1}.")]
            for j in range(n)]
    coul = [names.index(f"A{j + 1}.Fc") for j in range(n)]
    Fj = [np.empty((N, len(c))) for c in own]
    payload = np.empty((N, n, 4))
    k0 = robot.n_std - 10
    for rows, mb in _blocks(m):
        Y = robot.regressor(mb.q, mb.qd, mb.qdd)
        F = extras(robot, mb, settings, drive, qd_range=fr.get("qd_range"))
        rigid[rows] = Y[:, :, ind] @ beta
        z = np.zeros_like(mb.q)
        gravity[rows] = robot.regressor(mb.q, z, z)[:, :, ind] @ beta
        payload[rows] = Y[:, :, k0: k0 + 4]
        for j in range(n):
            Fj[j][rows] = F[:, j, own[j]]
            friction[rows, j] = F[:, j, fric[j]] @ x[fric[j]]
            sign[rows, j] = F[:, j, coul[j]]
    tau_hat = rigid + np.column_stack([Fj[j] @ x[own[j]] for j in range(n)])
    times, temps = [], []
    for lg in logs:
        rows = sample_rows(lg, settings)
        times.append(np.asarray(lg.time, float)[rows])
        t = getattr(lg, "temp", None)
        temps.append(None if t is None else np.asarray(t, float)[rows][:, [lg.index(a) for a in range(1, n + 1)]])
    temp = None if any(t is None for t in temps) else np.concatenate(temps)
    fs = [1.0 / lg.sample_time for lg in logs]
    cut = _cutoff(settings, min(fs))
    ctx = Context(q=m.q, qd=m.qd, tau=m.tau, gravity=gravity, rigid=rigid, sign=sign, friction=friction, temp=temp,
                  payload=payload, total_mass=float(np.sum(np.maximum(robot.pi_nominal[0::10], 0))),
                  log_rows=m.log_rows or (N,), cutoff=cut, time=np.concatenate(times))
    from kukaid.diagnose.noise import filtered_noise_floor

    floor = [filtered_noise_floor([lg.tau[:, lg.index(j + 1)] for lg in logs], fs, [_cutoff(settings, f) for f in fs],
                                  settings.order) for j in range(n)]
    return m, rigid, Fj, tau_hat, ctx, np.asarray(floor)


def _heldout(r: np.ndarray, tau: np.ndarray, Fj: list, shared: list | None, local: dict | None, folds: np.ndarray,
             K: int, w: np.ndarray, evaluate: Sequence[int] | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Held-out squared error per joint of ``r = tau - rigid`` explained by each joint's own columns
    ``Fj`` plus ``local`` {joint: (N, c) columns of that joint only} plus ``shared`` (per joint
    (N, s) columns whose coefficients all joints share), fitted on the other folds (weights ``w``
    per joint), on the folds ``evaluate`` (default all). Returns the sums of squared errors (K, n)
    and of squared torques (K, n) per fold (0 for the folds not evaluated), the coefficients
    fitted on all samples and the held-out squared error of every sample (N, n)."""
    n = r.shape[1]
    ks = [F.shape[1] + (local[j].shape[1] if local and j in local else 0) for j, F in enumerate(Fj)]
    ns = 0 if shared is None else shared[0].shape[1]
    off = np.concatenate([[0], np.cumsum(ks)]).astype(int)
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
    num, den, sq = np.zeros((K, n)), np.zeros((K, n)), np.zeros_like(r)
    for f in (range(K) if evaluate is None else evaluate):
        A = sum(p[0] for p in parts) - parts[f][0]
        b = sum(p[1] for p in parts) - parts[f][1]
        x = solve(A, b)
        rows = folds == f
        for j in range(n):
            pred = cols(j, rows) @ x[off[j]:off[j + 1]]
            if shared is not None:
                pred = pred + shared[j][rows] @ x[off[-1]:]
            sq[rows, j] = (r[rows, j] - pred) ** 2
            num[f, j] = float(np.sum(sq[rows, j]))
            den[f, j] = float(np.sum(tau[rows, j] ** 2))
    x_all = solve(sum(p[0] for p in parts), sum(p[1] for p in parts))
    return num, den, x_all, sq


def _rel(num: np.ndarray, den: np.ndarray) -> np.ndarray:
    """Relative error per joint of per-fold sums (K, n)."""
    return np.sqrt(num.sum(0) / np.maximum(den.sum(0), 1e-300))


def _gain_t(sq0: np.ndarray, sq: np.ndarray, den: np.ndarray, block: np.ndarray, joints: list[int]) -> float:
    """The held-out gain of a candidate (squared error before - after, each joint relative to its
    squared torque) summed per block of held-out samples: its mean over the blocks divided by its
    standard error (a t statistic; inf when every block gains alike)."""
    ids = np.unique(block[block >= 0])
    d = (sq0 - sq)[:, joints] / np.maximum(den[joints], 1e-300)
    g = np.array([float(d[block == b].sum()) for b in ids])
    if g.size < 2:
        return float("inf") if g.sum() > 0 else 0.0
    se = float(np.std(g, ddof=1)) / np.sqrt(g.size)
    return float(np.mean(g) / se) if se > 0 else (float("inf") if np.mean(g) > 0 else 0.0)


def _choose(A: np.ndarray, y: np.ndarray, B: np.ndarray) -> int:
    """The option (of ``B``: (N, O, c)) whose columns, fitted by least squares beside ``A`` (N, k),
    leave the smallest squared residual of ``y`` (N,)."""
    Q, _ = np.linalg.qr(A[:, np.any(A != 0, axis=0)]) if A.size else (np.zeros((A.shape[0], 0)), None)
    e = y - Q @ (Q.T @ y)
    N, O, c = B.shape
    Bf = B.reshape(N, O * c)
    Bp = (Bf - Q @ (Q.T @ Bf)).reshape(N, O, c)
    G = np.einsum("noc,nod->ocd", Bp, Bp) + 1e-12 * np.eye(c)[None] * (1.0 + np.einsum("noc,noc->o", Bp, Bp)[:, None, None])
    g = np.einsum("noc,n->oc", Bp, e)
    gain = np.einsum("oc,oc->o", g, np.linalg.solve(G, g[..., None])[..., 0])
    return int(np.argmax(gain))


def _with(local: dict, shared: list | None, cand: RobotCandidate, col: np.ndarray, n: int):
    """``local`` and ``shared`` with the candidate's columns ``col`` added."""
    if cand.joint is not None:
        j = cand.joint
        return {**local, j: np.concatenate([local[j], col], axis=1) if j in local else col}, shared
    new = [col[:, j, :] for j in range(n)]
    return local, new if shared is None else [np.concatenate([a, b], axis=1) for a, b in zip(shared, new)]


def _unseen(params: dict, logs: Sequence[Any]) -> tuple[list[Any], list[str]]:
    """The recordings to diagnose on: those the file was not fitted on, when there are at least two
    (the rigid body is fixed from the file, so on a recording it was fitted on its error is
    in-sample: small where the others' is not, and a candidate that tells that recording from the
    others, as a temperature that differs per recording does, would seem to predict the others);
    all of them otherwise. Returns the recordings and the names of those left out."""
    from kukaid.identify.robot_fit import log_fingerprint

    fps = set((params.get("provenance") or {}).get("log_fingerprints") or [])
    if len(logs) < 3 or not fps:
        return list(logs), []
    seen = [log_fingerprint(lg) in fps for lg in logs]
    if sum(not x for x in seen) < 2:
        return list(logs), []
    return ([lg for lg, x in zip(logs, seen) if not x],
            [str(lg.attrs.get("source_file") or f"log {k + 1}") for k, (lg, x) in enumerate(zip(logs, seen)) if x])


def _try(cand: RobotCandidate, ctx: Context, r, tau, Fj, shared, local, folds, K, w, held):
    """Held-out relative error per joint with the candidate, its options chosen on the training folds;
    the option chosen on all samples and the candidate's coefficients fitted on all samples (None
    when no option applies)."""
    n = r.shape[1]
    opts = cand.options(ctx)
    if not opts:
        return None
    if len(opts) == 1:
        pick, best_all = [0] * K, 0
        B = cand.columns(ctx, opts[0])
        B = B[:, None, :] if B.ndim == 2 else None
    else:
        j = cand.joint
        B = cand.batch(ctx, opts)
        parts = [Fj[j]] + ([local[j]] if j in local else []) + ([shared[j]] if shared is not None else [])
        A = np.concatenate(parts, axis=1)
        best_all = _choose(A, r[:, j], B)
        pick = [best_all if cand.shape_from_all_samples else _choose(A[folds != f], r[folds != f, j], B[folds != f])
                if f in held else -1 for f in range(K)]
    num, den, sq = np.zeros((K, n)), np.zeros((K, n)), np.zeros_like(r)

    def cols_of(o):
        return B[:, o, :] if B is not None else cand.columns(ctx, opts[o])

    for o in sorted(set(pick[f] for f in held)):
        loc, sh = _with(local, shared, cand, cols_of(o), n)
        a, b, _, q2 = _heldout(r, tau, Fj, sh, loc, folds, K, w, [f for f in held if pick[f] == o])
        num, den, sq = num + a, den + b, sq + q2
    loc, sh = _with(local, shared, cand, cols_of(best_all), n)
    _, _, x, _ = _heldout(r, tau, Fj, sh, loc, folds, K, w, [])
    c = cols_of(best_all).shape[-1]
    if cand.joint is None:
        coefs = x[-c:]
    else:
        j = cand.joint
        end = sum(F.shape[1] + (loc[i].shape[1] if i in loc else 0) for i, F in enumerate(Fj[:j + 1]))
        coefs = x[end - c:end]
    return num, den, sq, opts[best_all], coefs, cols_of(best_all)


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
    logs, fitted_on = _unseen(params, logs)
    m, rigid, Fj, tau_hat, ctx, floor = _signals(params, logs, robot)
    n = robot.n
    axes = list(range(1, n + 1))
    tau = m.tau
    r = tau - rigid
    folds, K, how = _folds(m, logs)
    held = list(range(K))
    in_sample = (np.linalg.norm(tau - tau_hat, axis=0) / np.maximum(np.linalg.norm(tau, axis=0), 1e-300)).tolist()
    rms = np.sqrt(np.mean(tau ** 2, axis=0))
    sig = np.maximum(np.std(tau - tau_hat, axis=0), 1e-9)
    w = 1.0 / sig ** 2
    # joints that carry gravity over the data: a counterbalance candidate each
    # (a counterbalance sits on a joint that carries the most gravity: at least half the largest range)
    g = ctx.gravity
    span = np.ptp(g, axis=0)
    grav = [j for j in range(n) if span[j] >= 0.5 * span.max() and np.std(g[:, j]) > 0.1 * np.sqrt(np.mean(tau[:, j] ** 2))]
    remaining = {c.name: c for c in robot_candidates(ctx, grav)}
    local: dict = {}
    shared = None
    num, den, _, sq0 = _heldout(r, tau, Fj, shared, local, folds, K, w, held)
    # blocks of the held-out samples (FOLDS contiguous blocks of each held-out recording, or the
    # blocks themselves): a named effect's held-out gain must stand out from its spread over them
    block = np.full(r.shape[0], -1)
    for f in held:
        idx = np.flatnonzero(folds == f)
        nb = FOLDS if K > 1 else 1
        block[idx] = f * FOLDS + np.minimum(np.arange(idx.size) * nb // max(idx.size, 1), nb - 1)
    err = _rel(num, den)
    fold_err = num
    before = err.copy()
    steps, rejected = [], []
    tried: list[dict] = []
    for rnd in range(max(0, max_steps)):
        best = None
        trials: list[dict] = []
        for name, cand in remaining.items():
            res = _try(cand, ctx, r, tau, Fj, shared, local, folds, K, w, held)
            if res is None:
                continue
            fnum, fden, fsq, opt, coefs, col = res
            gain_t = _gain_t(sq0, fsq, den.sum(0), block, cand.joints(ctx))
            e = _rel(fnum, fden)
            joints = cand.joints(ctx)
            info = cand.describe(ctx, opt, coefs)
            mb, ma = float(np.mean(err[joints])), float(np.mean(e[joints]))
            per_fold = (fnum[held][:, joints].sum(1) / np.maximum(fold_err[held][:, joints].sum(1), 1e-300)).tolist()
            trials.append({"name": name, "mean_before": mb, "mean_after": ma, "fold_sse_ratio": per_fold,
                           "gain_t": gain_t})
            worse = [f"A{k + 1}" for k in range(n) if e[k] > (1 + MARGIN) * err[k] + 1e-12]
            reason = None
            if ma > (1 - MARGIN) * mb:
                reason = f"held-out error {100 * mb:.2f} -> {100 * ma:.2f} % (needs a {100 * MARGIN:.0f} % drop)"
            elif worse:
                reason = f"makes {', '.join(worse)} worse on held-out data"
            elif gain_t < MIN_T:
                reason = (f"held-out error {100 * mb:.2f} -> {100 * ma:.2f} %, but the gain is {gain_t:.2g} x its "
                          f"standard error over the held-out blocks (needs {MIN_T:g})")
            else:
                reason = cand.implausible(ctx, opt, coefs) or None
            if reason is None and (best is None or (mb - ma) / mb > best[0]):
                best = ((mb - ma) / mb, name, e, joints, info, mb, ma, col, fnum, fsq, gain_t)
            elif reason is not None:
                rejected = [x_ for x_ in rejected if x_["name"] != name] + [{"name": name, "reason": reason}]
        if rnd == 0:
            tried = trials
        if best is None:
            break
        _, name, e, joints, info, mb, ma, col, fnum, fsq, gain_t = best
        cand = remaining.pop(name)
        rejected = [x_ for x_ in rejected if x_["name"] != name]
        local, shared = _with(local, shared, cand, col, n)
        steps.append({"name": name, "joints": [f"A{k + 1}" for k in joints], "params": {
            k: v for k, v in info.items() if not isinstance(v, list)}, "details": info,
            "mean_before": mb, "mean_after": ma, "gain_t": gain_t, "heldout_before": err.tolist(),
            "heldout_after": e.tolist(), "trials": trials})
        err, fold_err, sq0 = e, fnum, fsq
    return RobotDiagnosis(axes=axes, folds=how, before=before.tolist(), after=err.tolist(), steps=steps,
                          rejected=rejected, in_sample=in_sample, noise_floor=floor.tolist(), rms=rms.tolist(),
                          tried=tried, fitted_on=fitted_on)
