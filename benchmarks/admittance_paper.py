"""The paper's hand-guiding experiment (experiment 4) as a paired benchmark with a human arm, on
the plant family (kukaid.sim.family: half of it LuGre, a friction law the estimator was not built on).

Usage: python benchmarks/admittance_paper.py [--operators 30] [--seed-offsets 0,1000] [--cycles 0.024,0.012]
                                             [--plants family|paper] [--json] [--jobs N] [--sweep]
                                             [--params PARAMS.json] [--save RESULTS.json]
                                             [--arm human|spring] [--cutoff HZ] [--quick]

Operator i of a seed set (seed offset + i) meets member (i // 3) % 6 of the family in the order gms,
lugre, gms-sensor, lugre-posfric, gms-gravity, lugre-all, drawn from its seed (every member sees
every grip; the two laws alternate, so half the operators are on a LuGre plant), with that plant's own
parameter file (the truth with identification errors; for LuGre the closest Maxwell-slip elements).
--plants paper: the paper's A3 for everybody, the controller's model with fixed errors (below).
The firm grips also meet constant D 100, 150 and 200: the lightest constant damping with no firm run
counted as oscillating and no torque-stop trip is what the adaptive law is compared with on firm
grips (a D 50 that rings there is no fair reference: it is reported as ringing).

Every operator (a seeded person from kukaid.sim.human: a third each soft, ordinary and firm
grips) meets every controller with the same seed (the same person, the same sensor noise and
vibration): constant D in {35, 50, 70} and the adaptive (RBF) damping from D0 = 50, each at
24 ms and 12 ms control cycles.  Over a window from the grasp to the release + 1 s (the person lets go
when done, so the window is the run's own; the same window for both of a pair, which counts letting go
sooner, is printed beside the acceptance lines) it computes the paper's mean cost xi = mean(1/2 dG^2 + 1/2 lambda G^2) and mean squared dG (eq. 19)
on the estimated residual Gr and on the true hand torque; then, per pair (adaptive vs constant),
the mean paired difference with its 95 % confidence interval (t), paired wins and the Wilcoxon
signed-rank p-value; and per controller oscillations (runs of at least 4 successive half-cycles
of the hand torque, each 10 N·m peak to peak or more and shorter than 0.8 s, kukaid.control.metrics;
counted when one lasts more than 1.5 s after the stability monitor first acted on it, or more
than 2 s if it never acted), the longest such time (damp time), torque-stop trips, false detections after the release, end error (relative to the
person's move) and the estimated/true mean squared dG ratio.

The controller's model is the simulator's truth with fixed errors (Fc -5 %, Fs +4 %, Fv +6 %,
Izz +5 %, Mx -2 %, Maxwell-slip W -10 %), as an identified model would be, unless --params.
--sweep varies each of the paper's unstated constants (lambda, eta1, eta2, centres, width, m)
around the chosen value, at 24 ms, and reports adaptive vs D 50 on the true hand torque (a
changed lambda changes the cost too: both sides of the pair are then scored with it).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import sys
import time

import numpy as np

GRIPS = ("soft", "ordinary", "firm")


@dataclasses.dataclass(frozen=True)
class _SpringParams:
    grip: str
    q_start: float
    goal: float
    t_grasp: float
    move_time: float
    release_time: float
    K: float
    B: float
    delay: float
    max_torque: float


class SpringArm:
    """A second operator model, deliberately unlike kukaid.sim.human (the controller was never tuned
    on it): a pure spring-damper around a minimum-jerk move, the whole impedance acting through
    one transport delay, no co-contraction, no noise, no tremor, let go at a fixed time wherever
    the link is.  Stiffness log-uniform 60-1200 N·m/rad at the axis, damping ratio 0.05-0.3 of
    the arm + admittance inertia (20 kg·m²), delay 20-100 ms, move 0.2-0.5 rad in 1.5-3.5 s,
    force limit 40-80 N·m.  Grip class from K: soft < 150, ordinary < 400, firm above.
    """

    def __init__(self, seed: int, q0: float, t_start: float) -> None:
        rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x51]))
        K = float(math.exp(rng.uniform(math.log(60.0), math.log(1200.0))))
        d = float(rng.uniform(0.2, 0.5)) * (1.0 if rng.random() < 0.5 else -1.0)
        grip = "soft" if K < 150 else "ordinary" if K < 400 else "firm"
        self.p = _SpringParams(grip=grip, q_start=q0, goal=q0 + d, t_grasp=t_start,
                               move_time=float(rng.uniform(1.5, 3.5)), release_time=0.2, K=K,
                               B=2.0 * float(rng.uniform(0.05, 0.3)) * math.sqrt(K * 20.0),
                               delay=float(rng.uniform(0.02, 0.1)), max_torque=float(rng.uniform(40.0, 80.0)))
        self.t_release = t_start + self.p.move_time + 1.5
        self.released_on_target = False
        self.K_peak = K
        self._hist: list[tuple[float, float, float]] = []

    def __call__(self, t: float, q: float, qd: float) -> float:
        p = self.p
        self._hist.append((t, q, qd))
        while len(self._hist) > 2 and self._hist[1][0] <= t - p.delay:
            self._hist.pop(0)
        _, qs, qds = self._hist[0]
        if t < p.t_grasp or t > self.t_release + p.release_time:
            return 0.0
        x = min(max((t - p.t_grasp) / p.move_time, 0.0), 1.0)
        s, ds = x ** 3 * (10 - 15 * x + 6 * x * x), 30 * x * x * (1 - x) ** 2 / p.move_time
        xd, vd = p.q_start + (p.goal - p.q_start) * s, (p.goal - p.q_start) * ds
        g = min(1.0, (t - p.t_grasp) / 0.2, max(0.0, (self.t_release + p.release_time - t) / p.release_time))
        if t >= self.t_release and not self.released_on_target:
            self.released_on_target = abs(qs - p.goal) < max(0.01, 0.05 * abs(p.goal - p.q_start))
        return g * min(max(p.K * (xd - qs) + p.B * (vd - qds), -p.max_torque), p.max_torque)


def controller_model(params: dict | None = None):
    from kukaid.params import model_from_params
    from kukaid.sim import SimConfig

    if params is None:
        c = SimConfig()
        params = c.replace(Fc=c.Fc * 0.95, Fs=c.Fs * 1.04, Fv=c.Fv * 1.06, Izz=c.Izz * 1.05, Mx=c.Mx * 0.98,
                           ms_W=tuple(w * 0.9 for w in c.ms_W)).truth_params()
    return model_from_params(params)  # its Maxwell-slip state starts at zero, as run-admittance's:
    # the plant's initial pre-sliding state is not the controller's to know


def run_one(model, seed: int, damping: str, D: float, cycle: float, rbf=None, grip: str | None = None,
            duration: float = 13.0, lam: float = 0.05, coupling=None, arm: str = "human", cutoff: float = 5.0,
            with_run: bool = False, floor=None, plant=None):
    """One paired run; returns the window metrics (cost with ``lam``) plus run-level checks (and, with
    ``with_run``, the :class:`~kukaid.control.loop.AdmittanceRun` too: ``(metrics, run)``).
    ``floor(operator)``: a class used instead of the adaptive law's grip floor
    (:class:`~kukaid.control.stability.CouplingFloor`), made for this run's operator (admittance_oracle.py).
    ``plant`` (a :class:`kukaid.sim.family.Plant`): its truth and its own parameter file instead of the
    paper's A3 and ``model``."""
    from kukaid.robot import SimRobot
    from kukaid.control.loop import LoopConfig, run_admittance
    from kukaid.control.metrics import damping_delay, window_metrics
    from kukaid.sim import SimConfig, VirtualKRC4
    from kukaid.sim.operator import make_operator

    q0 = math.radians(30.0)
    kw = {"rbf": rbf} if rbf is not None else {}
    if coupling is not None:
        kw["coupling"] = coupling
    cfg = LoopConfig(damping=damping, D=D, cycle=cycle, duration=duration, cutoff=cutoff, **kw)
    t_op = cfg.init_time + cfg.init_rest + 0.8
    op = (SpringArm(seed, q0 + cfg.init_move, t_op) if arm == "spring" else
          make_operator("human", seed, q0 + cfg.init_move, t_start=t_op, grip=grip))
    if plant is not None:
        from kukaid.params import model_from_params

        model = model_from_params(plant.params)
    be = SimRobot(VirtualKRC4(plant.cfg if plant is not None else SimConfig(), seed=seed), q0, op)
    if floor is not None:
        from unittest import mock

        with mock.patch("kukaid.control.loop.CouplingFloor", floor(op)):
            run = run_admittance(be, model, cfg)
    else:
        run = run_admittance(be, model, cfg)
    d = run.data
    t0 = 0.012  # the run's time axis starts at the first measurement
    t_rel = op.t_release if math.isfinite(op.t_release) else math.inf
    t_to = min(t_rel + 1.0 - t0, float(d["time"][-1]))
    m = window_metrics(d, op.p.t_grasp - t0, t_to, lam)
    after = d["time"] > t_rel - t0 + op.p.release_time + 0.05
    damp, sustained = damping_delay(m["osc_runs"], [e["time"] for e in run.metrics.get("stability_log", [])])
    move = op.p.goal - op.p.q_start
    m.update(seed=seed, grip=op.p.grip, status=run.status, plant=plant.name if plant is not None else "paper",
             torque_stop=run.status.startswith("stopped: external torque"),
             false_after_release=int(np.sum(d["detected"][after])) if math.isfinite(t_rel) else 0,
             # of those, Γr against the hand's last torque: its release read as a push the other way (the rest:
             # the push itself, still seen through the estimator's delay)
             against_after_release=_against(d, after) if math.isfinite(t_rel) else 0,
             end_error=float(abs(d["q"][-1] - op.p.goal) / abs(move)),
             released_on_target=bool(op.released_on_target), K_peak=float(op.K_peak),
             oscillating=bool(sustained), damp_time=float(damp),
             stab_events=int(run.metrics.get("stability_events", 0)),
             stick_slip=float(run.metrics.get("stick_slip_margin", 0.0)))
    return (m, run) if with_run else m


def _against(d: dict, window: np.ndarray) -> int:
    """Cycles detected in ``window`` with Γr against the hand's torque as it last acted (before the window)."""
    hand = d["tau_ext_true"][~window]
    last = hand[np.abs(hand) > 0.3]
    sign = np.sign(last[-1]) if last.size else 0.0
    return int(np.sum(d["detected"][window] & (d["gamma_r"][window] * sign < 0)))


def paired(a: np.ndarray, b: np.ndarray) -> dict:
    """Adaptive ``a`` vs constant ``b`` (lower is better): mean difference a - b with 95 % CI (t),
    relative difference of the means, wins (a < b), Wilcoxon signed-rank p."""
    from scipy import stats

    ok = np.isfinite(a) & np.isfinite(b)
    a, b = a[ok], b[ok]
    d = a - b
    n = d.size
    mean = float(np.mean(d))
    half = float(stats.t.ppf(0.975, n - 1) * np.std(d, ddof=1) / math.sqrt(n)) if n > 1 else math.nan
    try:
        p = float(stats.wilcoxon(a, b).pvalue)
    except ValueError:
        p = math.nan
    return {"n": int(n), "mean_a": float(np.mean(a)), "mean_b": float(np.mean(b)), "diff": mean,
            "ci": [mean - half, mean + half], "rel": mean / float(np.mean(b)), "wins": int(np.sum(d < 0)),
            "wilcoxon_p": p}


CONTROLLERS = (("D35", "constant", 35.0), ("D50", "constant", 50.0), ("D70", "constant", 70.0),
               ("adaptive", "adaptive", 50.0))
#: constant dampings run on firm grips only, to find the lightest that is stable for all of them
FIRM_REFERENCES = (("D100", "constant", 100.0), ("D150", "constant", 150.0), ("D200", "constant", 200.0))


def _operators(n_ops: int, seed_offsets: tuple[int, ...], plants: str) -> list[tuple[int, str, object]]:
    """(seed, grip, plant) of every operator: seed set by seed set, grips by thirds, plant members
    in turn every three operators (so every member meets every grip)."""
    from kukaid.sim.family import FAMILY, plant

    # the estimator's own friction law and LuGre in turn, so half the operators meet a LuGre plant
    # (30 operators: 10 groups of 3, 5 on each law)
    order = [m for pair in zip(FAMILY[:3], FAMILY[3:]) for m in pair]

    ops = []
    for off in seed_offsets:
        for i in range(n_ops):
            seed = off + i
            ops.append((seed, GRIPS[i % 3], plant(order[(i // 3) % len(order)], seed) if plants == "family" else None))
    return ops


def _job(args):
    model, seed, damping, D, cyc, rbf, grip, arm, coupling, cutoff, plant = args
    return run_one(model, seed, damping, D, cyc, rbf=rbf, grip=grip, arm=arm, coupling=coupling, cutoff=cutoff,
                   plant=plant)


def benchmark(n_ops: int, cycles: tuple[float, ...], model, rbf=None, controllers=CONTROLLERS,
              arm: str = "human", coupling=None, cutoff: float = 5.0, seed_offsets: tuple[int, ...] = (0,),
              plants: str = "paper", firm_refs=(), jobs: int = 1) -> dict:
    """Operator i of each seed set has seed ``offset + i`` and grip ``GRIPS[i % 3]`` (the same for every
    controller); ``firm_refs`` controllers meet the firm grips only.  ``jobs`` worker processes."""
    from concurrent.futures import ProcessPoolExecutor

    ops = _operators(n_ops, seed_offsets, plants)
    out: dict = {}
    for cyc in cycles:
        plan = [(name, k, (model, seed, damping, D, cyc, rbf if damping == "adaptive" else None, grip, arm,
                           coupling if damping == "adaptive" else None, cutoff, pl))
                for name, damping, D in (*controllers, *firm_refs)
                for k, (seed, grip, pl) in enumerate(ops)
                if grip == "firm" or (name, damping, D) not in firm_refs]
        if jobs > 1:
            with ProcessPoolExecutor(jobs) as ex:
                done = list(ex.map(_job, [a for _, _, a in plan], chunksize=2))
        else:
            done = [_job(a) for _, _, a in plan]
        runs: dict[str, list[dict]] = {}
        for (name, k, _), r in zip(plan, done):
            runs.setdefault(name, []).append(r)
        res: dict = {"runs": runs, "per_controller": {}, "paired": {}}
        for name, rs in runs.items():
            col = lambda k: np.array([r[k] for r in rs], dtype=float)  # noqa: E731
            firm = [r for r in rs if r["grip"] == "firm"]
            res["per_controller"][name] = {
                "n": len(rs),
                "xi": float(np.mean(col("xi"))), "dgamma2": float(np.mean(col("dgamma2"))),
                "xi_true": float(np.mean(col("xi_true"))), "dgamma2_true": float(np.mean(col("dgamma2_true"))),
                "dgamma2_ratio": float(np.mean(col("dgamma2") ) / np.mean(col("dgamma2_true"))),
                "dgamma2_ratio_max": float(np.max(col("dgamma2_ratio"))),
                "dgamma2_ratio_over_2": int(np.sum(col("dgamma2_ratio") > 2.0)),
                "oscillating": int(np.sum(col("oscillating"))), "torque_stop": int(np.sum(col("torque_stop"))),
                "oscillating_firm": int(sum(r["oscillating"] for r in firm)),
                "torque_stop_firm": int(sum(r["torque_stop"] for r in firm)),
                "false_after_release": int(np.sum(col("false_after_release"))),
                "against_after_release": int(np.sum(col("against_after_release"))),
                "end_error_median": float(np.median(col("end_error"))), "end_error_max": float(np.max(col("end_error"))),
                "end_error_soft_max": float(np.max([r["end_error"] for r in rs if r["grip"] == "soft"] or [math.nan])),
                "stab_events": int(np.sum(col("stab_events"))), "osc_ptp_max": float(np.max(col("osc_ptp"))),
                "damp_time_max": float(np.max(col("damp_time"))),
                "xi_true_by_grip": {g: float(np.mean([r["xi_true"] for r in rs if r["grip"] == g] or [math.nan]))
                                    for g in GRIPS},
                "lugre_share": float(np.mean([r["plant"].startswith("lugre") for r in rs])),
            }
        ad = runs.get("adaptive")
        if ad:
            by_key = {(r["seed"], r["grip"]): r for r in ad}
            for name, rs in runs.items():
                if name == "adaptive":
                    continue
                res["paired"][name] = {}
                for key in ("xi", "dgamma2", "xi_true", "dgamma2_true"):
                    a = np.array([by_key[(r["seed"], r["grip"])][key] for r in rs])
                    b = np.array([r[key] for r in rs])
                    pr = paired(a, b)
                    for g in GRIPS:
                        sel = np.array([r["grip"] == g for r in rs])
                        pr[f"wins_{g}"] = int(np.sum(a[sel] < b[sel]))
                        pr[f"n_{g}"] = int(np.sum(sel))
                    res["paired"][name][key] = pr
            if "D50" in runs:  # the same window for both of a pair: the window ends at the release, and a
                # controller that lets the person finish sooner has a shorter one, its mean then over less rest
                d50 = runs["D50"]
                ad_w = np.array([by_key[(r["seed"], r["grip"])]["window"] for r in d50])
                d_w = np.array([r["window"] for r in d50])
                n_a, n_d = (ad_w[:, 1] - ad_w[:, 0]) / cyc + 1, (d_w[:, 1] - d_w[:, 0]) / cyc + 1
                n = np.maximum(n_a, n_d)  # after a release the hand torque is 0: the longer run's window
                a = np.array([by_key[(r["seed"], r["grip"])]["xi_true"] for r in d50]) * n_a / n
                b = np.array([r["xi_true"] for r in d50]) * n_d / n
                res["common_window"] = {**paired(a, b), "released_sooner": int(np.sum(ad_w[:, 1] < d_w[:, 1] - 1e-9)),
                                        "released_later": int(np.sum(ad_w[:, 1] > d_w[:, 1] + 1e-9))}
            # the lightest constant damping stable for every firm grip: the fair reference there
            stable = [(D, name) for name, damping, D in (*controllers, *firm_refs)
                      if damping == "constant" and name in runs
                      and res["per_controller"][name]["oscillating_firm"] == 0
                      and res["per_controller"][name]["torque_stop_firm"] == 0]
            if stable:
                D_ref, ref = min(stable)
                firm = [r for r in runs[ref] if r["grip"] == "firm"]
                a = np.array([by_key[(r["seed"], r["grip"])]["xi_true"] for r in firm])
                b = np.array([r["xi_true"] for r in firm])
                res["firm_reference"] = {"controller": ref, "D": D_ref, **paired(a, b)}
        out[f"{cyc:g}"] = res
    return out


def acceptance(res: dict) -> list[tuple[str, bool, str]]:
    """Issue 22's lines, each (line, holds, figures)."""
    rows = []
    for cyc, r in res.items():
        ms = f"{float(cyc) * 1000:.0f} ms"
        pc, pr = r["per_controller"], r["paired"].get("D50", {}).get("xi_true")
        if pr:
            ok = pr["diff"] < 0 and pr["ci"][1] < 0 and pr["wins"] >= 0.75 * pr["n"]
            rows.append((f"{ms}: adaptive vs D 50 on ξ (true), CI < 0, wins >= 75 %", ok,
                         f"{100 * pr['rel']:+.1f} %, CI [{pr['ci'][0]:+.3f}, {pr['ci'][1]:+.3f}], "
                         f"wins {pr['wins']}/{pr['n']}"))
        fr = r.get("firm_reference")
        rows.append((f"{ms}: firm grips, adaptive vs the lightest stable constant D, wins >= 80 %",
                     bool(fr) and fr["wins"] >= 0.8 * fr["n"],
                     f"vs {fr['controller']}: {100 * fr['rel']:+.1f} %, wins {fr['wins']}/{fr['n']}" if fr else
                     "no constant damping was stable for every firm grip"))
        ad = pc.get("adaptive", {})
        rows.append((f"{ms}: adaptive runs counted as oscillating = 0", ad.get("oscillating", 1) == 0,
                     f"{ad.get('oscillating')}"))
        stops = {n: p["torque_stop"] for n, p in pc.items() if n in ("adaptive", "D50")}
        rows.append((f"{ms}: torque-stop trips (adaptive, D 50) = 0", not any(stops.values()), f"{stops}"))
        false = {n: p["false_after_release"] for n, p in pc.items()}
        against = sum(p.get("against_after_release", 0) for p in pc.values())
        rows.append((f"{ms}: detections after any release = 0", not any(false.values()),
                     f"{sum(false.values())} cycles, {against} against the hand's last push (a release read as a push "
                     "the other way; the rest the push itself, seen through the estimator's delay)"))
        ratio = {n: round(p["dgamma2_ratio"], 2) for n, p in pc.items() if n in ("adaptive", "D50")}
        rows.append((f"{ms}: estimated/true mean squared dΓ <= 2", all(v <= 2 for v in ratio.values()), f"{ratio}"))
    return rows


def print_table(res: dict, n_ops: int) -> None:
    for cyc, r in res.items():
        print(f"\n== control cycle {float(cyc) * 1000:.0f} ms, {n_ops} operators (soft/ordinary/firm by thirds) ==")
        fr = r.get("firm_reference")
        if fr:
            print(f"firm grips: lightest constant damping stable for all of them: {fr['controller']}; adaptive vs it "
                  f"on ξ (true): {100 * fr['rel']:+.1f} %, CI [{fr['ci'][0]:+.3f}, {fr['ci'][1]:+.3f}], "
                  f"wins {fr['wins']}/{fr['n']}")
        cw = r.get("common_window")
        if cw:
            print(f"adaptive vs D50 on ξ (true) over the same window for both (grasp to the later release + 1 s): "
                  f"{100 * cw['rel']:+.1f} %, CI [{cw['ci'][0]:+.3f}, {cw['ci'][1]:+.3f}], wins {cw['wins']}/{cw['n']}; "
                  f"the adaptive law's person let go sooner in {cw['released_sooner']}, later in {cw['released_later']}")
        print(f"{'controller':>9} | {'xi Gr':>7} {'dG2 Gr':>7} | {'xi true':>7} {'dG2 true':>8} | {'dG2 est/true':>12} |"
              f" {'osc':>3} {'stop':>4} {'false':>5} | {'end err med/max (soft max)':>26} | {'stab ev':>7} {'damp s':>6}")
        for name, p in r["per_controller"].items():
            print(f"{name:>9} | {p['xi']:7.3f} {p['dgamma2']:7.4f} | {p['xi_true']:7.3f} {p['dgamma2_true']:8.4f} |"
                  f" {p['dgamma2_ratio']:5.2f} (max {p['dgamma2_ratio_max']:4.2f}) | {p['oscillating']:3d} {p['torque_stop']:4d}"
                  f" {p['false_after_release']:5d} | {100 * p['end_error_median']:6.1f}% / {100 * p['end_error_max']:5.1f}%"
                  f" ({100 * p['end_error_soft_max']:5.1f}%) | {p['stab_events']:7d} {p['damp_time_max']:6.2f}")
        runs = r["runs"]
        if "adaptive" in runs and "D50" in runs and len({x["plant"] for x in runs["adaptive"]}) > 1:
            print("per plant (adaptive vs D 50 on ξ true: wins; oscillating runs; cycles detected after a release):")
            for pl in sorted({x["plant"] for x in runs["adaptive"]}):
                ad = [x for x in runs["adaptive"] if x["plant"] == pl]
                d50 = [x for x in runs["D50"] if x["plant"] == pl]
                wins = sum(a["xi_true"] < b["xi_true"] for a, b in zip(ad, d50))
                print(f"  {pl:>14}: wins {wins:2d}/{len(ad):2d} | osc adaptive {sum(a['oscillating'] for a in ad)} "
                      f"D50 {sum(b['oscillating'] for b in d50)} | after release adaptive "
                      f"{sum(a['false_after_release'] for a in ad)} D50 {sum(b['false_after_release'] for b in d50)}")
        if r["paired"]:
            print("adaptive - constant (paired; negative = adaptive costs the person less):")
            print(f"{'vs':>4} {'measure':>12} | {'mean diff':>9} {'95% CI':>21} {'rel':>7} | {'wins':>6} "
                  f"{'soft/ord/firm':>13} | {'Wilcoxon p':>10}")
            for name, per in r["paired"].items():
                for key, pr in per.items():
                    print(f"{name:>4} {key:>12} | {pr['diff']:+9.4f} [{pr['ci'][0]:+9.4f}, {pr['ci'][1]:+9.4f}]"
                          f" {100 * pr['rel']:+6.1f}% | {pr['wins']:2d}/{pr['n']:2d} "
                          f"{pr['wins_soft']:>3d}/{pr['wins_ordinary']:d}/{pr['wins_firm']:d}{'':>6} | {pr['wilcoxon_p']:10.2g}")


def sweep(n_ops: int, model, cycle: float = 0.024) -> list[dict]:
    """Adaptive vs D 50 on the true hand torque, one unstated constant changed at a time."""
    from kukaid.control.rbf import RBFConfig
    from kukaid.control.stability import CouplingConfig

    base = RBFConfig(D0=50.0, D_min=15.0, D_max=100.0)
    variants = [("chosen", {})]
    variants += [(f"lam={v:.3g}", {"lam": v}) for v in (base.lam / 3, base.lam * 3)]
    variants += [(f"eta1={v:.3g}", {"eta1": v}) for v in (base.eta1 / 3, base.eta1 * 3)]
    variants += [(f"eta2={v:.3g}", {"eta2": v}) for v in (base.eta2 / 3, base.eta2 * 3)]
    variants += [(f"width={v:g}", {"width": v}) for v in (base.width / 2, base.width * 2)]
    variants += [(f"m={v}", {"m": v}) for v in (0, 3)]
    variants += [("centres x0.5", {"force_levels": tuple(0.5 * f for f in base.force_levels),
                                   "dforce_levels": tuple(0.5 * f for f in base.dforce_levels)}),
                 ("centres x2", {"force_levels": tuple(2 * f for f in base.force_levels),
                                 "dforce_levels": tuple(2 * f for f in base.dforce_levels)})]
    ref = [run_one(model, i, "constant", 50.0, cycle, grip=GRIPS[i % 3]) for i in range(n_ops)]
    variants += [(f"grip zeta={v:g}", {"zeta": v}) for v in (0.1, 0.4)]
    variants += [("grip escalate=1.6", {"escalate": 1.6}), ("no probe", {"probe": False}),
                 ("no grip floor", {"enabled": False})]
    rows = []
    for label, ch in variants:
        cpl = CouplingConfig(**ch) if set(ch) <= {f.name for f in dataclasses.fields(CouplingConfig)} and ch else None
        rbf = base if cpl is not None else dataclasses.replace(base, **ch)
        ad = [run_one(model, i, "adaptive", 50.0, cycle, rbf=rbf, grip=GRIPS[i % 3], lam=rbf.lam, coupling=cpl)
              for i in range(n_ops)]
        if rbf.lam != base.lam:  # the cost the law minimises, for both sides of the pair
            ref_l = [run_one(model, i, "constant", 50.0, cycle, grip=GRIPS[i % 3], lam=rbf.lam)
                     for i in range(n_ops)]
        else:
            ref_l = ref
        row = {"variant": label}
        for key in ("xi_true", "dgamma2_true"):
            pr = paired(np.array([r[key] for r in ad]), np.array([r[key] for r in ref_l]))
            row[key] = {k: pr[k] for k in ("rel", "wins", "n", "ci", "wilcoxon_p")}
        row["oscillating"] = int(sum(r["oscillating"] for r in ad))
        row["torque_stop"] = int(sum(r["torque_stop"] for r in ad))
        rows.append(row)
    return rows


def print_sweep(rows: list[dict]) -> None:
    print("\n== sensitivity of adaptive vs D 50 (true hand torque, 24 ms) to the unstated constants ==")
    print(f"{'variant':>14} | {'xi rel':>7} {'wins':>6} | {'dG2 rel':>7} {'wins':>6} | osc stop")
    for r in rows:
        x, d = r["xi_true"], r["dgamma2_true"]
        print(f"{r['variant']:>14} | {100 * x['rel']:+6.1f}% {x['wins']:2d}/{x['n']:2d} | {100 * d['rel']:+6.1f}% "
              f"{d['wins']:2d}/{d['n']:2d} | {r['oscillating']:3d} {r['torque_stop']:4d}")


def print_markdown(doc: dict) -> None:
    """The tables of docs/admittance.md from a --save file: adaptive vs every constant damping on ξ
    (true hand torque), then per controller, then the acceptance lines."""
    res = doc["results"]
    print("| cycle | adaptive vs | ξ (true) mean diff [95 % CI] | rel | wins (soft/ordinary/firm) | Wilcoxon p |")
    print("|---|---|---|---|---|---|")
    for cyc, r in res.items():
        for name, prs in r["paired"].items():
            pr = prs["xi_true"]
            print(f"| {float(cyc) * 1000:.0f} ms | {name} | {pr['diff']:+.3f} [{pr['ci'][0]:+.3f}, {pr['ci'][1]:+.3f}] "
                  f"| {100 * pr['rel']:+.1f} % | {pr['wins']}/{pr['n']} ({pr['wins_soft']}/{pr['wins_ordinary']}/"
                  f"{pr['wins_firm']}) | {pr['wilcoxon_p']:.2g} |")
    print()
    print("| cycle | controller | runs | mean ξ (true) | dΓ² est/true (largest run) | oscillating (firm) | torque stops "
          "| cycles detected after a release | end error median / max |")
    print("|---|---|---|---|---|---|---|---|---|")
    for cyc, r in res.items():
        for name, p in r["per_controller"].items():
            print(f"| {float(cyc) * 1000:.0f} ms | {name} | {p['n']} | {p['xi_true']:.2f} | {p['dgamma2_ratio']:.2f} "
                  f"({p['dgamma2_ratio_max']:.2f}) | {p['oscillating']} ({p['oscillating_firm']}) | {p['torque_stop']} "
                  f"| {p['false_after_release']} | {100 * p['end_error_median']:.1f} / {100 * p['end_error_max']:.1f} % |")
    print()
    for cyc, r in res.items():
        cw = r.get("common_window")
        if cw:
            print(f"- {float(cyc) * 1000:.0f} ms, adaptive vs D 50 on ξ (true) over the same window for both: "
                  f"{100 * cw['rel']:+.1f} %, CI [{cw['ci'][0]:+.3f}, {cw['ci'][1]:+.3f}], wins {cw['wins']}/{cw['n']}; "
                  f"released sooner {cw['released_sooner']}, later {cw['released_later']}")
    for line, ok, figs in acceptance(res):
        print(f"- {'holds' if ok else '**fails**'}: {line}: {figs}")
    if doc.get("sweep"):
        print()
        print("| variant | ξ rel | ξ wins | dΓ² rel | dΓ² wins | osc | stop |")
        print("|---|---|---|---|---|---|---|")
        for row in doc["sweep"]:
            x, d = row["xi_true"], row["dgamma2_true"]
            print(f"| {row['variant']} | {100 * x['rel']:+.1f} % | {x['wins']}/{x['n']} | {100 * d['rel']:+.1f} % | "
                  f"{d['wins']}/{d['n']} | {row['oscillating']} | {row['torque_stop']} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--operators", type=int, default=30)
    ap.add_argument("--cycles", default="0.024,0.012")
    ap.add_argument("--params", help="parameter file of the controller's model [simulator truth with errors]")
    ap.add_argument("--sweep", action="store_true", help="also the sensitivity sweep (24 ms)")
    ap.add_argument("--arm", choices=("human", "spring"), default="human",
                    help="operator model: the human arm of kukaid.sim.human, or the independent SpringArm")
    ap.add_argument("--controllers", default="D50,adaptive",
                    help="which controllers to run (of D35, D50, D70, adaptive) besides the firm references")
    ap.add_argument("--sweep-operators", type=int, default=15)
    ap.add_argument("--monitor-rule", choices=("double", "decay"), default="double",
                    help="adaptive mode: how the stability monitor raises the damping (CouplingConfig.monitor_rule)")
    ap.add_argument("--seed-offsets", default="0,1000",
                    help="seed sets: operator i of a set gets seed N + i (0: the operators the law was developed on; "
                         "1000: held out)")
    ap.add_argument("--plants", choices=("family", "paper"), default="family",
                    help="family: kukaid.sim.family by turns (half LuGre), each with its own parameter file; "
                         "paper: the paper's A3 and the model with fixed errors")
    ap.add_argument("--jobs", type=int, default=0, help="worker processes [the machine's cores]")
    ap.add_argument("--quick", action="store_true", help="3 operators, one seed set, 24 ms (the test suite runs it)")
    ap.add_argument("--cutoff", type=float, default=5.0,
                    help="the estimator's low-pass, Hz (LoopConfig.cutoff; the paper's 5 Hz), for every controller")
    ap.add_argument("--json", action="store_true", help="print the results as JSON instead of the table")
    ap.add_argument("--save", help="also write the JSON results to this file")
    ap.add_argument("--markdown", metavar="RESULTS.json",
                    help="print docs/admittance.md's markdown tables from saved results (no runs)")
    a = ap.parse_args()
    if a.markdown:
        with open(a.markdown) as f:
            print_markdown(json.load(f))
        return
    params = None
    if a.params:
        from kukaid.params import load_params

        params = load_params(a.params)
    model = controller_model(params)
    cycles = tuple(float(c) for c in a.cycles.split(","))
    offsets = tuple(int(x) for x in a.seed_offsets.split(","))
    if a.quick:
        a.operators, offsets, cycles = 3, offsets[:1], cycles[:1]
    jobs = a.jobs or os.cpu_count() or 1
    t = time.perf_counter()
    ctl = tuple(c for c in CONTROLLERS if c[0] in a.controllers.split(","))
    cpl = None
    if a.monitor_rule != "double":
        from kukaid.control.stability import CouplingConfig

        cpl = CouplingConfig(monitor_rule=a.monitor_rule)
    res = benchmark(a.operators, cycles, model, controllers=ctl, arm=a.arm, seed_offsets=offsets, coupling=cpl,
                    cutoff=a.cutoff, plants="paper" if a.params else a.plants, firm_refs=FIRM_REFERENCES, jobs=jobs)
    checks = acceptance(res)
    rows = sweep(a.sweep_operators, model) if a.sweep else None
    secs = time.perf_counter() - t
    from kukaid.jsonfile import jsonable

    doc = jsonable({"operators": a.operators, "seed_offsets": offsets, "plants": a.plants, "arm": a.arm,
                    "monitor_rule": a.monitor_rule, "cutoff": a.cutoff, "results": res, "sweep": rows,
                    "acceptance": [{"line": l, "holds": ok, "figures": f} for l, ok, f in checks], "seconds": secs})
    if a.save:
        with open(a.save, "w") as f:
            json.dump(doc, f)
    if a.json:
        json.dump(doc, sys.stdout)
        print()
        return
    print_table(res, a.operators * len(offsets))
    if rows is not None:
        print_sweep(rows)
    print("\n== issue 22's acceptance ==")
    for line, ok, fig in checks:
        print(f"{'holds' if ok else 'FAILS':>5}  {line}: {fig}")
    print(f"\n({secs:.0f} s)")


if __name__ == "__main__":
    main()
