"""The fleet's wear report (``kukaid fleet wear --report``): the axes ranked by evidence, every axis's
change of friction with its standard error, then per flagged axis its friction at the reference
temperature over the days, with the temperature and the CUSUM against its threshold.  Built from
the wear result alone (``kukaid.fleet-wear/1``)."""
from __future__ import annotations

import datetime as dt
from pathlib import Path
from typing import Any

from kukaid.report.layout import _add_table, _page, _subtitle, write_report

#: rows of the ranking table per page; flagged axes plotted, at most (the rest are in wear.json)
RANK_ROWS = 40
MAX_PLOTS = 60


def _footer(source: str) -> str:
    return f"kukaid fleet wear · {Path(source).name}" if source else "kukaid fleet wear"


def _pct(x: Any) -> str:
    return "-" if x is None else f"{100 * x:+.1f} %"


def _trend(t: dict) -> str:
    """The Fc trend per 30 days with its standard error: '+9.7±4.1 %' (a slope over a few days after the
    baseline, extrapolated: without its error it reads as wear)."""
    se = t.get("Fc_se")
    if se is None or se != se:  # an older file, or too few logs for a slope
        return _pct(t["Fc"])
    return f"{100 * t['Fc']:+.1f}±{100 * se:.1f} %"


def ranking_pages(result: dict, source: str = "") -> list:
    """Pages of the ranking table (every assessed axis, highest evidence first)."""
    axes = [a for a in result["axes"] if "evidence" in a]
    tm = result["temperature_model"]
    s = result["summary"]
    temp = (f"no temperature model ({tm.get('note') or 'no temperature logged'}): friction not normalised"
            if tm["T_ref"] is None else
            f"friction normalised to {tm['T_ref']:.1f} °C with the fleet's model: Fc {100 * tm['Fc_per_K']:+.2f} %/K, "
            f"Fv {100 * tm['Fv_per_K']:+.2f} %/K (spread across axes {100 * tm['slope_spread_per_K'][0]:.2f} %/K)")
    st = result["settings"]
    pages = []
    chunks = [axes[i:i + RANK_ROWS] for i in range(0, max(len(axes), 1), RANK_ROWS)]
    for k, chunk in enumerate(chunks):
        fig = _page("Fleet wear: axes ranked by evidence" + (f" ({k + 1}/{len(chunks)})" if len(chunks) > 1 else ""),
                    _footer(source))
        _subtitle(fig, f"{s['assessed']} {'axis' if s['assessed'] == 1 else 'axes'} assessed, {s['flagged']} flagged (of {s['axes']} in the table). {temp}. "
                       f"Evidence = largest CUSUM of the standardised residuals / threshold (flagged above 1; "
                       f"threshold set for at most {100 * st['alpha']:.1f} % of healthy axes ever flagged). "
                       "ΔFc, ΔFv: last week against the baseline at the reference temperature; Fc per 30 d: the "
                       "slope after the baseline ± its standard error.")
        cells = [[a["robot"], f"A{a['axis']}", "yes" if a["flagged"] else "no", a["first_flagged"] or "-",
                  f"{a['evidence']:.2f}", _pct(a["change"]["Fc"]), _pct(a["change"]["Fv"]),
                  _trend(a["trend_per_30d"]), f"{a.get('fleet_z', 0):+.1f}", str(a["n_logs"])] for a in chunk]
        if not cells:
            cells = [["-"] * 10]
        h = min(0.86, 0.021 * (len(cells) + 1))
        ax = fig.add_axes([0.06, 0.92 - h, 0.88, h])
        tab = _add_table(ax, cells, ["robot", "axis", "flagged", "first flagged", "evidence", "ΔFc", "ΔFv",
                                     "Fc per 30 d", "fleet z", "logs"], fontsize=7)
        for (r, _), cell in tab.get_celld().items():
            if r > 0 and r <= len(chunk) and chunk[r - 1]["flagged"]:
                cell.set_facecolor("#f6d5d0")
        pages.append(fig)
    return pages


def change_se(a: dict) -> list[float]:
    """Standard error of an assessed axis's change of Fc and Fv (relative): the mean of its last week
    (up to 7 logs) against its baseline's, each log with the baseline's day-to-day scatter (the
    temperature slope's error left out)."""
    nb = a["baseline"]["logs"]
    last = min(7, a["n_logs"] - nb)
    return [(1 + a["change"][k]) * s * (1 / last + 1 / nb) ** 0.5
            for k, s in zip(("Fc", "Fv"), a["baseline"]["scatter_rel"])]


def change_page(result: dict, source: str = "") -> Any:
    """Every assessed axis as a point: its change of Fc against that of Fv at the reference
    temperature, with their standard errors (:func:`change_se`); the flagged axes red and named."""
    axes = [a for a in result["axes"] if "evidence" in a]
    fig = _page("Fleet wear: friction change per axis", _footer(source))
    _subtitle(fig, "ΔFc and ΔFv of every assessed axis: the last week (up to 7 logs) against its baseline, at the "
                   "reference temperature. Error bars: one standard error of the change, from the baseline's "
                   "day-to-day scatter (the temperature slope's error left out). Red: flagged (the CUSUM, which "
                   "weighs every log after the baseline, crossed its threshold).")
    ax = fig.add_axes([0.12, 0.32, 0.8, 0.56])
    for flagged, color, label in ((False, "0.45", "not flagged"), (True, "C3", "flagged")):
        sel = [a for a in axes if a["flagged"] == flagged]
        if sel:
            se = [change_se(a) for a in sel]
            ax.errorbar([100 * a["change"]["Fc"] for a in sel], [100 * a["change"]["Fv"] for a in sel],
                        xerr=[100 * e[0] for e in se], yerr=[100 * e[1] for e in se], fmt="o", ms=3, color=color,
                        elinewidth=0.6, label=f"{label} ({len(sel)})")
    for a in [a for a in axes if a["flagged"]][:20]:
        ax.annotate(f"{a['robot']} A{a['axis']}", (100 * a["change"]["Fc"], 100 * a["change"]["Fv"]), fontsize=6,
                    xytext=(3, 3), textcoords="offset points")
    ax.axhline(0, color="0.7", lw=0.6)
    ax.axvline(0, color="0.7", lw=0.6)
    ax.set_xlabel("ΔFc (%)", fontsize=8)
    ax.set_ylabel("ΔFv (%)", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.legend(fontsize=7, loc="upper left")
    return fig


def _dates(ds: list[str]) -> list:
    return [dt.date.fromisoformat(d) for d in ds]


def axis_page(a: dict, source: str = "") -> Any:
    """One flagged axis: Fc and Fv at the reference temperature (raw values faint), the motor
    temperature, and the CUSUM with its threshold and the first flag."""
    s = a["series"]
    d = _dates(s["date"])
    fig = _page(f"{a['robot']} A{a['axis']}: friction trend", _footer(source))
    _subtitle(fig, f"Flagged on {a['first_flagged']} (evidence {a['evidence']:.2f}). Baseline {a['baseline']['from']} to "
                   f"{a['baseline']['to']} ({a['baseline']['logs']} logs). Change at the reference temperature: "
                   f"Fc {_pct(a['change']['Fc'])}, Fv {_pct(a['change']['Fv'])}; temperature coefficient "
                   f"Fc {100 * a['temperature_coefficient']['Fc']:+.2f} %/K. Faint: as fitted; solid: at the reference "
                   "temperature.")
    nb = a["baseline"]["logs"]
    flag = dt.date.fromisoformat(a["first_flagged"]) if a["first_flagged"] else None
    for k, (name, unit) in enumerate((("Fc", "N·m"), ("Fv", "N·m·s/rad"))):
        ax = fig.add_axes([0.1, 0.70 - 0.22 * k, 0.78, 0.18])
        ax.plot(d, s[name], ".", color="0.7", ms=3, label="as fitted")
        ax.plot(d, s[name + "_ref"], "o-", color="C0", ms=3, lw=1, label="at reference temperature")
        ax.axvspan(d[0], d[nb - 1], color="C2", alpha=0.12, label="baseline")
        if flag is not None:
            ax.axvline(flag, color="C3", lw=1, label="first flagged")
        ax.set_ylabel(f"{name} ({unit})", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.legend(fontsize=6, loc="upper left")
    ax = fig.add_axes([0.1, 0.30, 0.78, 0.14])
    temps = [t if t is not None else float("nan") for t in s["temp"]]
    ax.plot(d, temps, "s-", color="C1", ms=2, lw=0.8)
    ax.set_ylabel("motor temp. (°C)", fontsize=8)
    ax.tick_params(labelsize=7)
    ax = fig.add_axes([0.1, 0.08, 0.78, 0.17])
    ax.plot(d, s["cusum"], "-", color="C4", lw=1.2, label="CUSUM")
    ax.axhline(a["threshold"], color="C3", ls="--", lw=1, label=f"threshold {a['threshold']:.2f}")
    if flag is not None:
        ax.axvline(flag, color="C3", lw=1)
    ax.set_ylabel("CUSUM (σ)", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.legend(fontsize=6, loc="upper left")
    for x in fig.axes:
        for lab in x.get_xticklabels():
            lab.set_rotation(20)
    return fig


def write_wear_report(path: str | Path, result: dict, source: str = "") -> int:
    """Write the wear report (PDF, atomically); returns the number of pages."""
    pages = ranking_pages(result, source) + [change_page(result, source)]
    flagged = [a for a in result["axes"] if a.get("flagged")][:MAX_PLOTS]
    pages += [axis_page(a, source) for a in flagged]
    return write_report(path, pages, title="kukaid fleet wear report")
