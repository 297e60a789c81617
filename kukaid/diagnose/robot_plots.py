"""PDF pages of a robot diagnosis (:class:`~kukaid.diagnose.robot.RobotDiagnosis`): where the gap
closed, per joint.

Page 1: the held-out relative errors, the table of steps (effect, joints, held-out RMSE before ->
after per joint in multiples of the noise floor) and of the candidates tried. Then one page per
joint: its held-out residual (measured minus predicted, filtered as the diagnosis compares them)
before and after the named effects against time, and for each named effect on the joint, before
and after it against the effect's own coordinate (A<j>'s position for a counterbalance or a ripple,
its motor temperature for thermal friction, its load torque for load-dependent friction), the
noise floor drawn (a perfect model's RMSE)."""
from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from kukaid.diagnose.plots import _binned, summary_pages, write_pages
from kukaid.diagnose.robot import RobotDiagnosis
from kukaid.models.robot_effects import parse, wrist_mix

TITLE = "kukaid diagnose: a robot's gap and the effects found"


def coordinate(result: RobotDiagnosis, step: dict, j: int) -> tuple[np.ndarray, str] | None:
    """The coordinate a step's effect acts along on joint ``j`` (0-based), and its label; None for
    an effect without one (a payload). A coupled wrist friction's: the velocity of the motor whose
    friction the joint feels most; a gear elasticity's: its joint's rigid-body torque (its spring's)."""
    s = result.series.signals
    kind, _ = parse(step["name"])
    opt = step.get("option") or {}
    if kind in ("counterbalance", "position_ripple"):
        return s.q[:, j], f"A{j + 1} position (rad)"
    if kind == "thermal_friction":
        return s.temp[:, j], f"A{j + 1} motor temperature (degC)"
    if kind == "load_dependent_friction":
        load = opt.get("load", "gravity")
        return (s.gravity if load == "gravity" else s.rigid)[:, j], f"A{j + 1} {load} load torque (N·m)"
    if kind == "coupled_wrist_friction" and s.qd is not None:
        # the motor whose friction the joint feels most: A4's and A5's motor 5, A6's motor 6
        n = s.q.shape[1]
        m = 1 if j == n - 1 else 0
        return s.qd @ wrist_mix(n, opt)[m], f"motor {5 + m} velocity, joint units (rad/s)"
    if kind == "gear_elasticity":
        e = parse(step["name"])[1]
        return s.rigid[:, e], f"A{e + 1} rigid-body torque (N·m; the gear's deflection times its stiffness)"
    return None


def _x_floor(result: RobotDiagnosis, rel, j: int) -> str:
    """Joint ``j``'s RMSE (``rel`` of its RMS) in multiples of its noise floor; over 999 "> 999"; "n/a"
    where the torque was smoothed at the source, as the LWR4+'s (its floor is not known)."""
    if result.floor_unknown[j]:
        return "n/a"
    x = float(rel[j]) * result.rms[j] / max(result.noise_floor[j], 1e-300)
    return f"{x:.1f}" if x <= 999 else "> 999"


def tables(result: RobotDiagnosis) -> list[tuple[list[str], list[list[str]]]]:
    """The steps (held-out RMSE per joint in multiples of the noise floor, before -> after) and the
    candidates tried in the first round (their joints' held-out relative error and verdict)."""
    axes = [f"A{a}" for a in result.axes]
    steps = [[str(k + 1), st["name"]] + [f"{_x_floor(result, st['heldout_before'], j)} -> "
                                         f"{_x_floor(result, st['heldout_after'], j)}" if a in st["joints"] else "-"
                                         for j, a in enumerate(axes)]
             for k, st in enumerate(result.steps)]
    why = {r["name"]: r["reason"] for r in result.rejected}
    tried = [[t["name"], f"{100 * t['mean_before']:.2f} %", f"{100 * t['mean_after']:.2f} %", f"{t['gain_t']:.2g}",
              "named" if t["name"] in result.names else textwrap.shorten(why.get(t["name"], "-"), 58)]
             for t in result.tried]
    out = [(["step", "effect"] + [f"{a} (x floor)" for a in axes], steps)] if steps else []
    return out + ([(["candidate (first round)", "held out", "after", "gain t", "verdict (not named: why)"], tried,
                    [0.24, 0.09, 0.09, 0.07, 0.51])] if tried else [])


def _plot(ax, x, before, after, floor: float | None, label: str, points: bool) -> None:
    """Residual before and after (None: the one residual) against ``x``: points (when ``points``)
    or lines, binned means, the noise floor (None: not known, not drawn)."""
    for r, name, c in ((before, "before" if after is not None else "residual", "C0"), (after, "after", "C3")):
        if r is None:
            continue
        rms = float(np.sqrt(np.nanmean(r ** 2)))
        if points:
            ax.plot(x, r, ".", ms=1.2, alpha=0.35, color=c, label=f"{name}: RMSE {rms:.3g} N·m", rasterized=True)
            bx, by = _binned(x, r)
            ax.plot(bx, by, "-", lw=1.8, color=c)
        else:
            ax.plot(x, r, "-", lw=0.5, color=c, label=f"{name}: RMSE {rms:.3g} N·m", rasterized=True)
    for y in (floor, -floor) if floor is not None else ():
        ax.axhline(y, color="k", ls="--", lw=0.7, label="noise floor (±RMS)" if y > 0 else None)
    ax.axhline(0, color="k", lw=0.4)
    ax.set_xlabel(label, fontsize=8)
    ax.set_ylabel("held-out residual (N·m)", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.legend(fontsize=7, loc="upper right")


def _in_time(result: RobotDiagnosis, *ys: np.ndarray) -> list[np.ndarray]:
    """The recordings one after the other (each from its own start, 1 s apart; NaN between them so
    a line does not join them): the time s, then each of ``ys`` (N,) likewise."""
    t = np.asarray(result.series.time, float)
    outs: list[list] = [[] for _ in range(1 + len(ys))]
    at, start = 0, 0.0
    for k in result.series.log_rows:
        seg = t[at:at + k]
        for o, y in zip(outs, (seg - seg[0] + start, *(y_[at:at + k] for y_ in ys))):
            o += [y, [np.nan]]
        start += float(seg[-1] - seg[0]) + 1.0 if k else 0.0
        at += k
    return [np.concatenate(o) for o in outs]


def page_joint(result: RobotDiagnosis, j: int):
    """Joint ``j``'s page: its held-out residual before and after the named effects against time;
    before and after each named effect on it against that effect's coordinate."""
    import matplotlib.pyplot as plt

    res = result.series.residuals
    floor = None if result.floor_unknown[j] else result.noise_floor[j]
    mine = [(k, st) for k, st in enumerate(result.steps) if f"A{j + 1}" in st["joints"]]
    coords = [(k, st, coordinate(result, st, j)) for k, st in mine]
    coords = [c for c in coords if c[2] is not None]
    fig, axs = plt.subplots(1 + len(coords), 1, figsize=(8.27, 11.69), squeeze=False)
    names = ", ".join(st["name"] for _, st in mine) or "none"
    t, r0, r1 = _in_time(result, res[0][:, j], res[-1][:, j])
    _plot(axs[0, 0], t, r0, r1 if result.steps else None, floor, "time (s; the held-out recordings one after another)",
          points=False)
    axs[0, 0].set_title(f"before and after every named effect (on A{j + 1}: {names})" if result.steps else
                        "the file's own terms refitted: no effect named", fontsize=9)
    for ax, (k, st, (x, label)) in zip(axs[1:, 0], coords):
        _plot(ax, x, res[k][:, j], res[k + 1][:, j], floor, label, points=True)
        ax.set_title(f"step {k + 1}: before and after {st['name']}", fontsize=9)
    rel = result.before[j], result.after[j]
    gap = (f"{100 * rel[0]:.1f} -> {100 * rel[1]:.1f} % (the noise floor is not known: the torque is smoothed at "
           "the source)" if floor is None else f"{_x_floor(result, result.before, j)} -> "
           f"{_x_floor(result, result.after, j)} x the noise floor ({100 * rel[0]:.1f} -> {100 * rel[1]:.1f} %)")
    fig.suptitle(textwrap.fill(f"A{j + 1}: held-out residual, measured - predicted (filtered as compared); RMSE {gap}"
                               + ("" if mine else "; no effect named"), 90), fontsize=10)
    fig.tight_layout(rect=(0, 0, 1, 0.95))
    return fig


def write_robot_report(result: RobotDiagnosis, path: str | Path) -> int:
    """Write the robot diagnosis' pages to ``path`` (PDF, atomically); returns the number of pages."""
    if result.series is None:
        raise ValueError("this diagnosis holds no residuals to draw")

    def pages():
        head = [ln for ln in result.lines() if not ln.startswith("not named: ")]
        if not result.steps:
            head.append("No effect is named: the pages show the held-out residuals of the file's own terms.")
        figs, _ = summary_pages(head, tables(result), TITLE, row=0.017)
        return figs + [page_joint(result, j) for j in range(len(result.axes))]

    return write_pages(pages, path)
