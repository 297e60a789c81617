"""Wear watch: per robot and axis, friction normalised to a reference temperature, its trend, and a
flag when it leaves its own baseline (and the fleet's common drift) by more than the evidence allows.

The method, per axis (rows of the fleet table with ``status == "ok"``; one friction model per axis):

1. ``y = ln Fc`` and ``ln Fv`` (relative changes), the log's mean motor temperature ``T``.
2. Baseline: the axis's first ``n_b`` logs (default a quarter of them, 5 to 14).
3. Temperature model, fitted across the fleet's own baselines: ``y = a_i + b_i (T - T_ref)``; the
   fleet slope ``b`` is the pooled within-axis slope, each axis's ``b_i`` its own slope shrunk
   toward ``b`` by the spread of the slopes across axes (empirical Bayes).  ``T_ref`` is the fleet's
   median baseline temperature.  Friction at ``T_ref``: ``y* = y - b_i (T - T_ref)``.  A baseline
   spanning less than ``MIN_TEMP_SPREAD_K`` (3 K) of temperature gives no slope (it takes the fleet's);
   with none wider there is no temperature model.
4. The fleet's common drift on each day (the median over axes of ``y*`` minus its baseline mean,
   with at least ``min_fleet`` axes that day) is removed, so a change every axis shares (a colder
   plant, a new grease batch) flags no axis; an axis must leave the fleet's course too.
5. Standardised residuals ``z`` against the axis's baseline mean and scatter (the scatter blended
   with the fleet's pooled one), Fc and Fv combined as ``(z_c + z_v) / sqrt(2 + 2 rho)``.
6. A one-sided CUSUM on the logs after the baseline, ``S = max(0, S + min(z, 4) - k)``; the axis is
   flagged on the first day ``S > h``.  ``h`` is set by Monte Carlo of this very procedure
   (baseline estimation included) under no wear, so that at most ``alpha`` of healthy axes are
   ever flagged over the table's horizon (default ``alpha`` 0.5 %, half the 1 % allowed, a margin
   for residuals that are not quite normal).

Evidence of an axis: ``max S / h`` (> 1: flagged), the relative change of Fc and Fv at ``T_ref``
(last week against the baseline), their trend per 30 days with its standard error (the slope over
the days after the baseline, extrapolated), and how far the axis's change stands from the fleet's
changes (robust z).
"""
from __future__ import annotations

import datetime as dt
import functools
import math
from collections import Counter
from dataclasses import asdict, dataclass
from typing import Any, Sequence

import numpy as np

from kukaid.errors import KukaidError

SCHEMA = "kukaid.fleet-wear/1"
# A baseline whose motor temperatures span less than this determines no temperature slope: a log's own
# heating by its friction moves its mean temperature by tenths of a kelvin (more on a wearing axis), so
# a slope fitted to such a spread is friction against itself, not against the temperature.
MIN_TEMP_SPREAD_K = 3.0


@dataclass(frozen=True)
class WearSettings:
    """Settings of the wear watch.

    alpha : share of healthy axes allowed ever to be flagged over the horizon (the threshold's target).
    k : CUSUM reference value, in standard deviations (detects shifts of about 2 k fastest).
    baseline : logs in an axis's baseline (None: a quarter of its logs, 5 to 14).
    clip : standardised residuals are clipped at this (one wild fit cannot flag an axis).
    min_fleet : axes needed on a day to estimate the fleet's common drift (else none is removed).
    prior_dof : weight (degrees of freedom) of the fleet's pooled scatter in each axis's scatter.
    mc_paths, mc_seed : Monte Carlo of the threshold.
    """

    alpha: float = 0.005
    k: float = 0.5
    baseline: int | None = None
    clip: float = 4.0
    min_fleet: int = 8
    prior_dof: float = 10.0
    mc_paths: int = 20000
    mc_seed: int = 20260105

    def __post_init__(self) -> None:
        if not 0 < self.alpha < 0.5:
            raise KukaidError(f"wear: alpha must be in (0, 0.5), got {self.alpha}")
        if self.baseline is not None and self.baseline < 3:
            raise KukaidError(f"wear: the baseline needs at least 3 logs, got {self.baseline}")


def baseline_size(n: int, settings: WearSettings) -> int:
    """Logs in the baseline of an axis with ``n`` logs."""
    if settings.baseline is not None:
        return settings.baseline
    return int(min(14, max(5, n // 4)))


@functools.lru_cache(maxsize=64)
def threshold(n_base: int, horizon: int, k: float, alpha: float, clip: float, prior_dof: float,
              paths: int = 20000, seed: int = 20260105) -> float:
    """CUSUM threshold h: the (1 - alpha) quantile of ``max_t S_t`` over ``horizon`` logs after a
    baseline of ``n_base`` logs, for healthy axes (normal residuals; the baseline mean and the
    blended scatter estimated as :func:`assess` does).  Deterministic (seeded)."""
    if horizon <= 0:
        return math.inf
    rng = np.random.default_rng(seed)
    base = rng.standard_normal((paths, n_base))
    mu = base.mean(axis=1)
    s2 = base.var(axis=1, ddof=1)
    s = np.sqrt((prior_dof * 1.0 + (n_base - 1) * s2) / (prior_dof + n_base - 1))
    x = rng.standard_normal((paths, horizon))
    z = np.minimum((x - mu[:, None]) / s[:, None], clip)
    S = np.zeros(paths)
    Smax = np.zeros(paths)
    for t in range(horizon):
        S = np.maximum(0.0, S + z[:, t] - k)
        Smax = np.maximum(Smax, S)
    return float(np.quantile(Smax, 1.0 - alpha))


def _days(dates: Sequence[str]) -> np.ndarray:
    d0 = dt.date.fromisoformat(min(dates))
    return np.array([(dt.date.fromisoformat(d) - d0).days for d in dates], dtype=float)


@dataclass
class _Axis:
    robot: str
    axis: int
    dates: list
    T: np.ndarray
    y: np.ndarray  # (n, 2): ln Fc, ln Fv
    nb: int
    model: str
    dropped: int
    left_out: str = ""


def _axes(rows: Sequence[dict], settings: WearSettings) -> tuple[list[_Axis], list[dict]]:
    groups: dict[tuple[str, int], list[dict]] = {}
    for r in rows:
        if r.get("status") != "ok" or r.get("axis") is None or (r.get("kind") or "fit") != "fit":
            continue
        groups.setdefault((str(r["robot"]), int(r["axis"])), []).append(r)
    out, short = [], []
    for (robot, axis), rs in sorted(groups.items()):
        models = [str(r.get("friction_model")) for r in rs]
        model = max(sorted(set(models)), key=models.count)  # the most common; a tie the same in every run
        mine = [r for r in rs if str(r.get("friction_model")) == model]
        use = [r for r in mine if _pos(r.get("Fc")) and _pos(r.get("Fv"))]
        zero = len(mine) - len(use)
        byday: dict[str, dict] = {}
        for r in sorted(use, key=lambda r: r["date"]):
            byday.setdefault(r["date"], r)  # one log a day (the first)
        use = list(byday.values())
        dropped = len(rs) - len(use)
        n = len(use)
        nb = baseline_size(n, settings)
        why = _left_out(models, model, zero, len(mine) - zero - len(use))
        if n < nb + 1:
            short.append({"robot": robot, "axis": axis, "flagged": False, "first_flagged": None, "n_logs": n,
                          "note": f"too few logs ({n}; a baseline of {nb} and at least one more are needed)"
                                  + (f"; {why}" if why else ""), **({"left_out": why} if why else {})})
            continue
        T = np.array([r["temp_mean"] if r.get("temp_mean") is not None else np.nan for r in use], dtype=float)
        y = np.log(np.array([[r["Fc"], r["Fv"]] for r in use], dtype=float))
        out.append(_Axis(robot, axis, [r["date"] for r in use], T, y, nb, model, dropped, why))
    return out, short


def _left_out(models: Sequence[str], model: str, zero: int, same_day: int = 0) -> str:
    """Why some of an axis's fitted rows (their friction ``models``) are not used: those of another
    friction model than ``model`` (its most common), ``zero`` of ``model`` with Fc or Fv on its
    bound 0 (their logarithm is compared), and ``same_day`` more logs of a day that has one already
    (one log a day: the first in the table's order); "" when none is left out for those reasons."""
    other = Counter(m for m in models if m != model)
    parts = []
    if other:
        n = sum(other.values())
        parts.append(f"{n} of its {len(models)} fitted logs are of {' and '.join(sorted(other))}, not mixed with its "
                     f"{len(models) - n} {model} fits (fleet fit --friction-model stribeck or coulomb-viscous fits "
                     "every log with one model)")
    if zero:
        parts.append(f"{zero} with Fc or Fv at 0 (on its bound: no relative change to follow)")
    if same_day:
        parts.append(f"{same_day} more {'log' if same_day == 1 else 'logs'} of a day already logged (one log a day: "
                     "the first by path)")
    return "; ".join(parts)


def _pos(v: Any) -> bool:
    return v is not None and math.isfinite(float(v)) and float(v) > 0


def _no_temperature_model(note: str) -> dict:
    """The temperature model when there is none (friction not normalised), and why (``note``)."""
    return {"T_ref": None, "b": [0.0, 0.0], "per_axis": {}, "pred": {}, "spread": [0.0, 0.0], "note": note}


def _temperature_model(axes: list[_Axis]) -> dict:
    """Fleet slope b (per column) and each axis's shrunk slope, from the baselines."""
    have_T = [a for a in axes if np.all(np.isfinite(a.T[:a.nb]))]
    if not have_T:  # why: no temperature, or baselines with a day without one
        note = ("no temperature logged" if not any(np.isfinite(a.T).any() for a in axes) else
                "no axis has a temperature for every log of its baseline")
        return _no_temperature_model(note)
    T_ref = float(np.median(np.concatenate([a.T[:a.nb] for a in have_T])))
    spans = [float(np.ptp(a.T[:a.nb])) for a in have_T]
    wide = [a for a, span in zip(have_T, spans) if span >= MIN_TEMP_SPREAD_K]
    narrow = [a for a, span in zip(have_T, spans) if span < MIN_TEMP_SPREAD_K]
    if not wide:
        return _no_temperature_model(f"no axis's baseline spans {MIN_TEMP_SPREAD_K:g} K of motor temperature (the "
                                     f"widest {max(spans):.2g} K): the temperature slope is not determined")
    sxx, sxy, res_var, b_ols, se2 = [], [], [], [], []
    for a in wide:
        Tb, yb = a.T[:a.nb], a.y[:a.nb]
        dT = Tb - Tb.mean()
        dy = yb - yb.mean(axis=0)
        Sxx = float(dT @ dT)
        Sxy = dT @ dy
        sxx.append(Sxx)
        sxy.append(Sxy)
        bi = Sxy / Sxx if Sxx > 0 else np.zeros(2)
        r = dy - np.outer(dT, bi)
        v = (r ** 2).sum(axis=0) / max(a.nb - 2, 1)
        res_var.append(v)
        b_ols.append(bi)
        se2.append(v / Sxx if Sxx > 0 else np.full(2, np.inf))
    sxx, sxy = np.array(sxx), np.array(sxy)
    b = sxy.sum(axis=0) / max(sxx.sum(), 1e-12)
    b_ols, se2, res_var = np.array(b_ols), np.array(se2), np.array(res_var)
    ok = np.isfinite(se2).all(axis=1)
    tau2 = np.maximum(np.var(b_ols[ok], axis=0) - np.mean(se2[ok], axis=0), 0.0) if ok.sum() > 2 else np.zeros(2)
    per, pred = {}, {}
    for a in narrow:  # a baseline too narrow for a slope takes the fleet's
        per[(a.robot, a.axis)] = b
        pred[(a.robot, a.axis)] = (float(a.T[:a.nb].mean()), np.full(2, np.inf))
    for a, Sxx_i, Sxy_i, v in zip(wide, sxx, sxy, res_var):
        lam = v / tau2 if np.all(tau2 > 0) else np.full(2, np.inf)
        # a baseline without a temperature spread and without scatter (Sxx + lam = 0) does not determine
        # the axis's slope: it takes the fleet's, as without a spread of the slopes
        lam = np.where(Sxx_i + lam > 0, lam, np.inf)
        with np.errstate(invalid="ignore"):  # lam inf (no spread): inf/inf, not taken
            bi = np.where(np.isfinite(lam), (Sxy_i + lam * b) / (Sxx_i + lam), b)
        per[(a.robot, a.axis)] = bi
        # what the slope's error adds to a prediction at T: (T - mean T of the baseline)^2 / (Sxx + lam)
        pred[(a.robot, a.axis)] = (float(a.T[:a.nb].mean()), Sxx_i + lam)
    return {"T_ref": T_ref, "b": b.tolist(), "per_axis": per, "pred": pred, "spread": np.sqrt(tau2).tolist()}


def assess(rows: Sequence[dict], settings: WearSettings | None = None, source: str = "the table") -> dict:
    """The wear verdict of every axis in the fleet table's ``rows`` (dicts of
    :data:`kukaid.fleet.table.COLUMNS`, read from ``source``); the content of ``wear.json`` (schema
    ``kukaid.fleet-wear/1``).

    Raises
    ------
    KukaidError : a table of another task than fleet fit (validate, diagnose), no fitted row at all, or no
        axis with logs enough for a baseline and one more.
    """
    settings = settings or WearSettings()
    kinds = sorted({str(r.get("kind") or "fit") for r in rows})
    if kinds and "fit" not in kinds:  # the table of fleet validate or diagnose: no friction in it
        raise KukaidError(f"{source}: not a table of fleet fit (its rows are of fleet {', '.join(kinds)}): fleet wear "
                          "assesses the friction of a fit table (kukaid fleet fit)")
    axes, short = _axes(rows, settings)
    if not axes and not short:
        raise KukaidError(f"{source}: the table has no fitted rows (status ok) to assess")
    if not axes:  # a verdict of no axis would read as "none flagged": no wear seen, where none was looked for
        most = max(short, key=lambda a: a["n_logs"])
        why = f"; {most['left_out']}" if most.get("left_out") else ""
        raise KukaidError(f"{source}: no axis has logs enough to assess: the most, {most['n_logs']} ({most['robot']} "
                          f"A{most['axis']}), are fewer than a baseline of {baseline_size(most['n_logs'], settings)} "
                          f"and one more{why}")
    tm = _temperature_model(axes)
    T_ref = tm["T_ref"]
    # friction at T_ref, relative to the axis's baseline mean
    ystar, mu = {}, {}
    for a in axes:
        bi = tm["per_axis"].get((a.robot, a.axis), np.zeros(2))
        T = np.where(np.isfinite(a.T), a.T, T_ref if T_ref is not None else 0.0)
        ys = a.y - np.outer(T - (T_ref if T_ref is not None else 0.0), bi)
        ystar[(a.robot, a.axis)] = ys
        mu[(a.robot, a.axis)] = ys[:a.nb].mean(axis=0)
    # the fleet's common drift per day (median over axes), removed when enough axes share a day
    byday: dict[str, list] = {}
    for a in axes:
        key = (a.robot, a.axis)
        for d, r in zip(a.dates, ystar[key] - mu[key]):
            byday.setdefault(d, []).append(r)
    common = {d: (np.median(np.array(v), axis=0) if len(v) >= settings.min_fleet else np.zeros(2))
              for d, v in byday.items()}
    resid, scat, infl, dof = {}, [], {}, {}
    for a in axes:
        key = (a.robot, a.axis)
        c = np.array([common[d] for d in a.dates])
        ys = ystar[key] - c
        mu[key] = ys[:a.nb].mean(axis=0)
        r = ys - mu[key]
        resid[key] = r
        # a residual after the baseline is a prediction: its variance grows by the baseline mean's
        # (1/n_b) and the slope's error at that temperature; the baseline residuals lost the
        # degrees of freedom of the mean and of the (shrunk) slope
        if key in tm["pred"]:
            Tm, den = tm["pred"][key]
            T = np.where(np.isfinite(a.T), a.T, Tm)
            infl[key] = np.sqrt(1.0 + 1.0 / a.nb + np.outer((T - Tm) ** 2, 1.0 / den))
            lost = 1.0 + np.minimum(float(((a.T[:a.nb] - Tm) ** 2).sum()) / den, 1.0)
        else:
            infl[key] = np.full((len(a.dates), 2), math.sqrt(1.0 + 1.0 / a.nb))
            lost = np.ones(2)
        dof[key] = np.maximum(a.nb - lost, 1.0)
        scat.append((r[:a.nb] ** 2).sum(axis=0) / dof[key])
    pooled = np.sqrt(np.median(np.array(scat), axis=0)) if scat else np.ones(2)
    allb = np.concatenate([resid[(a.robot, a.axis)][:a.nb] for a in axes]) if axes else np.zeros((2, 2))
    scatters = len(allb) > 2 and bool(np.all(allb.std(axis=0) > 1e-12))  # else no correlation to estimate
    rho = float(np.corrcoef(allb[:, 0], allb[:, 1])[0, 1]) if scatters else 0.0
    rho = 0.0 if not math.isfinite(rho) else max(min(rho, 0.99), -0.99)
    out_axes = []
    horizon = max((len(a.dates) - a.nb for a in axes), default=0)
    changes = []
    for a in axes:
        key = (a.robot, a.axis)
        r = resid[key]
        s2 = (settings.prior_dof * pooled ** 2 + (r[:a.nb] ** 2).sum(axis=0)) / (settings.prior_dof + dof[key])
        s = np.sqrt(np.maximum(s2, 1e-18))
        z2 = r / (s * infl[key])
        z = (z2[:, 0] + z2[:, 1]) / math.sqrt(2 + 2 * rho)
        h = threshold(a.nb, horizon, settings.k, settings.alpha, settings.clip, settings.prior_dof,
                      settings.mc_paths, settings.mc_seed)
        S, Smax, first = 0.0, 0.0, None
        cus = [0.0] * a.nb
        for t in range(a.nb, len(z)):
            S = max(0.0, S + min(float(z[t]), settings.clip) - settings.k)
            cus.append(S)
            Smax = max(Smax, S)
            if first is None and S > h:
                first = a.dates[t]
        ys = ystar[key]
        last = ys[-min(7, len(ys) - a.nb):]
        change = np.exp(last.mean(axis=0) - ys[:a.nb].mean(axis=0)) - 1.0
        changes.append(change)
        days = _days(a.dates)
        post = slice(a.nb, None)
        trend, trend_se = np.zeros(2), np.full(2, math.nan)
        if len(days[post]) >= 3 and np.ptp(days[post]) > 0:
            trend = np.array([np.polyfit(days[post], ys[post, j], 1)[0] for j in range(2)]) * 30.0
            # a slope over a few noisy days extrapolated to 30: its standard error from one log's scatter
            trend_se = 30.0 * s / math.sqrt(float(np.sum((days[post] - days[post].mean()) ** 2)))
        bi = tm["per_axis"].get(key, np.zeros(2))
        base_level = np.exp(ys[:a.nb].mean(axis=0))
        out_axes.append({
            "robot": a.robot, "axis": a.axis, "flagged": first is not None, "first_flagged": first,
            "evidence": round(Smax / h, 4) if math.isfinite(h) else 0.0,
            "cusum_max": round(Smax, 4), "threshold": round(h, 4), "n_logs": len(a.dates),
            "friction_model": a.model, "rows_not_used": a.dropped, **({"left_out": a.left_out} if a.left_out else {}),
            "baseline": {"from": a.dates[0], "to": a.dates[a.nb - 1], "logs": a.nb,
                         "Fc": float(base_level[0]), "Fv": float(base_level[1]),
                         "scatter_rel": [float(x) for x in s]},
            "temperature_coefficient": {"Fc": float(bi[0]), "Fv": float(bi[1]), "unit": "1/K (relative)"},
            "change": {"Fc": float(change[0]), "Fv": float(change[1]), "unit": "relative, last week vs baseline, at T_ref"},
            "trend_per_30d": {"Fc": float(trend[0]), "Fv": float(trend[1]), "Fc_se": float(trend_se[0]),
                              "Fv_se": float(trend_se[1]), "days": float(np.ptp(days[post])),
                              "unit": "relative per 30 days, the slope over the days after the baseline; _se: one "
                                      "standard error from the baseline's day-to-day scatter"},
            "series": {"date": list(a.dates), "temp": [None if not math.isfinite(x) else float(x) for x in a.T],
                       "Fc": np.exp(a.y[:, 0]).tolist(), "Fv": np.exp(a.y[:, 1]).tolist(),
                       "Fc_ref": np.exp(ys[:, 0]).tolist(), "Fv_ref": np.exp(ys[:, 1]).tolist(),
                       "z": [float(x) for x in z], "cusum": cus},
        })
    if changes:
        ch = np.array(changes).mean(axis=1)
        med = float(np.median(ch))
        mad = float(np.median(np.abs(ch - med))) * 1.4826 or 1e-12
        for ax, c in zip(out_axes, ch):
            ax["fleet_z"] = round((float(c) - med) / mad, 3)
    out_axes.sort(key=lambda d: (-d["evidence"], d["robot"], d["axis"]))
    all_axes = out_axes + short
    return {
        "schema": SCHEMA,
        "settings": asdict(settings),
        "temperature_model": {"T_ref": T_ref, "Fc_per_K": tm["b"][0], "Fv_per_K": tm["b"][1],
                              "slope_spread_per_K": tm["spread"], "unit": "relative friction change per kelvin",
                              **({"note": tm["note"]} if "note" in tm else {})},
        "residual_correlation_Fc_Fv": rho,
        "summary": {"axes": len(all_axes), "assessed": len(out_axes),
                    "flagged": sum(1 for a in out_axes if a["flagged"])},
        "axes": all_axes,
    }


def lines(result: dict, top: int = 20) -> list[str]:
    """A short table for the terminal: the axes ranked by evidence."""
    s = result["summary"]
    tmod = result["temperature_model"]
    out = [f"{s['assessed']} {'axis' if s['assessed'] == 1 else 'axes'} assessed, {s['flagged']} flagged (of {s['axes']})",
           "temperature model: " + (f"none ({tmod.get('note') or 'no temperature logged'})" if tmod["T_ref"] is None
                                    else f"Fc {100 * tmod['Fc_per_K']:+.2f} %/K, Fv {100 * tmod['Fv_per_K']:+.2f} %/K "
                                    f"about {tmod['T_ref']:.1f} °C")]
    ranked = [a for a in result["axes"] if "evidence" in a]
    if ranked:
        out.append(f"{'robot':<10} {'axis':>4} {'flag':>5} {'first flagged':>13} {'evidence':>8} {'ΔFc':>12} "
                   f"{'ΔFv':>12}")
    for a in ranked[:top]:
        sc = (a.get("baseline") or {}).get("scatter_rel") or [math.nan, math.nan]
        moved = [f"{100 * a['change'][k]:+.1f}±{100 * sc[j]:.1f}%" for j, k in enumerate(("Fc", "Fv"))]
        out.append(f"{a['robot']:<10} {'A' + str(a['axis']):>4} {'yes' if a['flagged'] else 'no':>5} "
                   f"{a['first_flagged'] or '-':>13} {a['evidence']:8.2f} {moved[0]:>12} {moved[1]:>12}")
    if ranked:  # what the figures are, so a reader can weigh them
        out.append("evidence: the largest CUSUM over its threshold (above 1: flagged); ΔFc, ΔFv: the last week "
                   "against the baseline at T_ref, ± the baseline's day-to-day scatter (one log's)")
    left = [a for a in ranked if a.get("left_out")]
    for a in left[:5]:  # assessed on fewer logs than were fitted, and why
        out.append(f"{a['robot']:<10} {'A' + str(a['axis']):>4} assessed on {a['n_logs']} logs: {a['left_out']}")
    if len(left) > 5:
        out.append(f"... and {len(left) - 5} more assessed axes with logs left out (the verdict file lists them)")
    short = [a for a in result["axes"] if "evidence" not in a]
    for a in short[:5]:  # not assessed, and why (a baseline needs that many logs and one more)
        out.append(f"{a['robot']:<10} {'A' + str(a['axis']):>4} not assessed: {a.get('note', '')}")
    if len(short) > 5:
        n = len(short) - 5
        out.append(f"... and {n} more ax{'i' if n == 1 else 'e'}s not assessed (the verdict file lists them)")
    return out
