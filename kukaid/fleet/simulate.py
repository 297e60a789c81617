"""A simulated fleet from the virtual KR C4: robots, days, motor temperature, wear; the truth apart.

Every axis of every robot gets its own truth, drawn around the paper's A3 (one-axis logs) or
around the URDF's robot (whole-arm logs, :func:`kukaid.sim.robot_truth.draw_truth`): friction
(Fc, Fs, Fv) and the rigid body spread by ``spread`` (relative, log-normal), and a temperature
coefficient of friction ``kappa`` (1/K, drawn in ``kappa_range``: friction falls as the grease
warms) about ``T_ref``.  Each day each robot runs one short identification motion at that day's
motor temperature (``temp_mean`` ± ``temp_swing`` °C, uniform, drawn per robot and day), logged
as the ``temp`` dataset.  A share ``wear_share`` of the axes wear: from an onset day (uniform between a
quarter and a half of the period) their friction (Fc, Fs, Fv, and the pre-sliding
saturation) grows linearly to ``1 + w`` on the last day, w uniform in ``wear_range``.

Output folder: ``logs/{robot}/{date}/A{axis}.h5`` (whole arm: ``arm.h5``), ``manifest.csv``
(``robot,axis,date,path``), ``truth.json`` (``kukaid.fleet-truth/1``: every axis's truth, its
wear, and every day's temperature).  The logs carry no truth in their attributes.
"""
from __future__ import annotations

import csv
import datetime as dt
import io
import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from kukaid.errors import OptionError

TRUTH_SCHEMA = "kukaid.fleet-truth/1"
START = "2026-01-05"


@dataclass(frozen=True)
class FleetSimConfig:
    """What to simulate (units: °C, 1/K, relative shares).

    robots : number of robots (names R001, R002, ...).   days : days of logs, one log per robot and day.
    axes : axes logged one by one (one-axis logs); ignored with ``whole_arm``.
    whole_arm : one six-axis log per robot and day (the KR 6 R700 sixx of the virtual KR C4).
    wear_share : share of the axes that wear (at least one when > 0).
    wear_range : (low, high) friction growth over the period of a wearing axis, relative.
    temp_mean, temp_swing : motor temperature of a day, uniform in mean ± swing, °C.
    kappa_range : (low, high) relative friction change per kelvin, 1/K.   T_ref : °C where friction is nominal.
    spread : relative (log-normal sigma) spread of every axis's truth around the nominal.
    noise : torque noise sigma of a one-axis log, N·m.
    seed : seed of every draw (truth, temperatures, wear, noise).   start : first day, YYYY-MM-DD.
    """

    robots: int = 10
    days: int = 30
    axes: tuple[int, ...] = (3,)
    whole_arm: bool = False
    wear_share: float = 0.08
    wear_range: tuple[float, float] = (0.2, 0.5)
    temp_mean: float = 32.0
    temp_swing: float = 15.0
    kappa_range: tuple[float, float] = (-0.008, -0.003)
    T_ref: float = 25.0
    spread: float = 0.2
    noise: float = 0.5
    seed: int = 0
    start: str = START

    def __post_init__(self) -> None:
        checks = [("robots", self.robots, 1, 100_000), ("days", self.days, 1, 100_000),
                  ("wear_share", self.wear_share, 0.0, 1.0), ("temp_swing", self.temp_swing, 0.0, 60.0),
                  ("spread", self.spread, 0.0, 1.0), ("noise", self.noise, 0.0, 100.0)]
        for name, v, lo, hi in checks:
            if not (isinstance(v, (int, float)) and math.isfinite(v) and lo <= v <= hi):
                raise OptionError(f"fleet simulate: {name} must be {lo:g} to {hi:g}, got {v!r}")
        if not self.whole_arm and (not self.axes or any(a not in range(1, 7) for a in self.axes)):
            raise OptionError(f"fleet simulate: axes must be numbers 1 to 6, got {list(self.axes)}")
        lo, hi = self.wear_range
        if not 0 <= lo <= hi <= 5:
            raise OptionError(f"fleet simulate: wear range must be 0 <= low <= high <= 5, got {lo:g}, {hi:g}")
        try:
            dt.date.fromisoformat(self.start)
        except ValueError:
            raise OptionError(f"fleet simulate: start must be a date YYYY-MM-DD, got {self.start!r}") from None

    def dates(self) -> list[str]:
        d0 = dt.date.fromisoformat(self.start)
        return [(d0 + dt.timedelta(days=k)).isoformat() for k in range(self.days)]

    def robot_names(self) -> list[str]:
        return [f"R{k + 1:03d}" for k in range(self.robots)]

    def axis_list(self) -> tuple[int, ...]:
        return tuple(range(1, 7)) if self.whole_arm else tuple(self.axes)


def wear_factor(day: int | np.ndarray, onset: float, total: float, days: int) -> np.ndarray:
    """Friction multiplier of a wearing axis on ``day`` (0-based): 1 before ``onset``, then linear
    to ``1 + total`` on the last day."""
    day = np.asarray(day, dtype=float)
    span = max(days - 1 - onset, 1.0)
    return 1.0 + total * np.clip((day - onset) / span, 0.0, 1.0)


def draw_fleet(cfg: FleetSimConfig) -> dict:
    """The fleet's truth: per axis (friction scale factors, kappa, wear) and per robot and day (temperature).

    Wearing axes are a random ``wear_share`` of all axes; each one's onset is uniform between a
    quarter and a half of the period (days), so the first quarter is the axes' healthy baseline.
    """
    rng = np.random.default_rng(np.random.SeedSequence([int(cfg.seed), 0xF1EE7]))
    names, axes, days = cfg.robot_names(), cfg.axis_list(), cfg.days
    all_axes = [(r, a) for r in names for a in axes]
    n_wear = int(round(cfg.wear_share * len(all_axes)))
    if cfg.wear_share > 0:
        n_wear = max(n_wear, 1)
    wearing = set(rng.choice(len(all_axes), size=n_wear, replace=False).tolist()) if n_wear else set()
    out_axes = []
    for k, (r, a) in enumerate(all_axes):
        f = np.exp(cfg.spread * rng.standard_normal(4))
        kappa = float(rng.uniform(*cfg.kappa_range))
        w = k in wearing
        total = float(rng.uniform(*cfg.wear_range)) if w else 0.0
        onset = float(rng.uniform(0.25, 0.5) * (days - 1)) if w else None
        out_axes.append({"robot": r, "axis": a, "friction_factor": float(f[0]), "viscous_factor": float(f[1]),
                         "inertia_factor": float(f[2]), "gravity_factor": float(f[3]), "kappa": kappa,
                         "T_ref": cfg.T_ref, "wearing": w, "wear_total": total, "wear_onset_day": onset,
                         "wear_onset_date": None if onset is None else cfg.dates()[int(math.ceil(onset))]})
    temps = {r: (cfg.temp_mean + cfg.temp_swing * rng.uniform(-1, 1, days)).round(2).tolist() for r in names}
    return {"schema": TRUTH_SCHEMA, "config": _cfg_dict(cfg), "axes": out_axes, "temperature": temps,
            "dates": cfg.dates(), "seed_sequence": [int(cfg.seed), 0xF1EE7]}


def _cfg_dict(cfg: FleetSimConfig) -> dict:
    d = asdict(cfg)
    d["axes"] = list(cfg.axes)
    d["wear_range"] = list(cfg.wear_range)
    d["kappa_range"] = list(cfg.kappa_range)
    return d


def _one_axis_truth(ax: dict, base, noise: float):
    """The SimConfig of one axis (without the day's wear and temperature)."""
    ff, fv, fi, fg = ax["friction_factor"], ax["viscous_factor"], ax["inertia_factor"], ax["gravity_factor"]
    return base.replace(axis=int(ax["axis"]), Fc=base.Fc * ff, Fs=base.Fs * ff, Fv=base.Fv * fv,
                        ms_W=tuple(w * ff for w in base.ms_W), Izz=base.Izz * fi, Mx=base.Mx * fg,
                        noise_sigma=noise)


def day_config(ax: dict, day: int, T: float, days: int, noise: float):
    """SimConfig of a one-axis truth ``ax`` (from :func:`draw_fleet`) on ``day`` at motor temperature T (°C)."""
    from kukaid.sim import SimConfig

    cfg = _one_axis_truth(ax, SimConfig(), noise)
    w = float(wear_factor(day, ax["wear_onset_day"], ax["wear_total"], days)) if ax["wearing"] else 1.0
    return cfg.replace(Fc=cfg.Fc * w, Fs=cfg.Fs * w, Fv=cfg.Fv * w, ms_W=tuple(x * w for x in cfg.ms_W),
                       T_amb=T, T0=T, effects={"thermal_drift": {"kappa": ax["kappa"], "T_ref": ax["T_ref"]}})


def daily_trajectory(axis: int):
    """The short daily identification motion of one axis: a 10 s multi-sine and point-to-point moves
    (about 30 s; :func:`kukaid.excite.validation.validation`)."""
    from kukaid.excite import generate

    return generate("validation", sine_time=10.0, ramp=2.0, axis=axis)


def _strip(log, seed: int, extra: dict | None = None):
    """The log as a controller would give it: q, tau, temp; no truth in its attributes."""
    from kukaid import __version__
    from kukaid.logs import AxisLog

    attrs = {"source": "virtual-krc4 (kukaid fleet simulate)", "seed": seed, "sample_time": float(np.median(np.diff(log.time))),
             "kukaid_version": __version__, **(extra or {})}
    return AxisLog(time=log.time, q=log.q, tau=log.tau, axes=log.axes, temp=log.temp, attrs=attrs)


def simulate_robot(robot: str, truth: dict, outdir: str, traj: Any = None) -> list[dict]:
    """Write every log of ``robot`` (all days, its axes) under ``outdir``; return manifest rows.

    Runs on a Dask worker (one robot per task); ``traj`` is the whole-arm trajectory (or None)."""
    from kukaid.logs import write_hdf5
    from kukaid.sim import VirtualKRC4

    cfg = FleetSimConfig(**{**truth["config"], "axes": tuple(truth["config"]["axes"]),
                            "wear_range": tuple(truth["config"]["wear_range"]),
                            "kappa_range": tuple(truth["config"]["kappa_range"])})
    rix = cfg.robot_names().index(robot)
    axes = [a for a in truth["axes"] if a["robot"] == robot]
    temps = truth["temperature"][robot]
    rows = []
    root = Path(outdir)
    trajs = {}
    for d, date in enumerate(truth["dates"]):
        T = float(temps[d])
        folder = root / "logs" / robot / date
        if cfg.whole_arm:
            seed = int(np.random.SeedSequence([cfg.seed, rix, 0, d]).generate_state(1)[0])
            log = _arm_log(cfg, robot, rix, axes, d, T, traj, seed)
            name = f"logs/{robot}/{date}/arm.h5"
            write_hdf5(log, root / name)
            rows.append({"robot": robot, "axis": "", "date": date, "path": name})
            continue
        for ax in axes:
            a = int(ax["axis"])
            if a not in trajs:
                trajs[a] = daily_trajectory(a)
            seed = int(np.random.SeedSequence([cfg.seed, rix, a, d]).generate_state(1)[0])
            sim = VirtualKRC4(day_config(ax, d, T, cfg.days, cfg.noise), seed=seed)
            log = _strip(sim.run(trajs[a]), seed)
            name = f"logs/{robot}/{date}/A{a}.h5"
            folder.mkdir(parents=True, exist_ok=True)
            write_hdf5(log, root / name)
            rows.append({"robot": robot, "axis": a, "date": date, "path": name})
    return rows


def arm_trajectory(robot: str = "kr6-r700-sixx"):
    """The daily whole-arm motion: a one-period 10 s Fourier excitation (a quick design)."""
    from kukaid.excite.fourier import fourier

    return fourier(robot, period=10.0, periods=1, iterations=3, starts=2, seed=0)


def _arm_log(cfg: FleetSimConfig, robot: str, rix: int, axes: list[dict], day: int, T: float, traj: Any, seed: int):
    from dataclasses import replace

    from kukaid.logs import AxisLog
    from kukaid.sim.robot_plant import RobotSimConfig, VirtualRobotKRC4, load_model
    from kukaid.sim.robot_truth import draw_truth

    rc = RobotSimConfig(sample_time=0.012)
    base = draw_truth(rc.robot, load_model(rc.robot), seed=1000 + rix + 7919 * cfg.seed, size=cfg.spread)
    fc, fv = base.Fc.copy(), base.Fv.copy()
    for ax in axes:
        j = int(ax["axis"]) - 1
        w = float(wear_factor(day, ax["wear_onset_day"], ax["wear_total"], cfg.days)) if ax["wearing"] else 1.0
        s = (1.0 + ax["kappa"] * (T - ax["T_ref"])) * w
        fc[j] = base.Fc[j] * ax["friction_factor"] * s
        fv[j] = base.Fv[j] * ax["viscous_factor"] * s
    truth = replace(base, Fc=fc, Fv=fv, Fs=fc.copy())
    log = VirtualRobotKRC4(rc, seed=seed, truth=truth).run(traj)
    rng = np.random.default_rng(seed)
    temp = T + 0.05 * np.arange(6)[None, :] + 0.02 * rng.standard_normal(log.q.shape)
    out = AxisLog(time=log.time, q=log.q, tau=log.tau, axes=log.axes, temp=temp, attrs={})
    return _strip(out, seed, {"robot": rc.robot})


def write_manifest(path: Path, rows: Sequence[dict]) -> None:
    """The manifest CSV ``robot,axis,date,path`` (atomic)."""
    from kukaid.atomic import write_text_atomic

    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=["robot", "axis", "date", "path"], lineterminator="\n")
    w.writeheader()
    for r in sorted(rows, key=lambda r: (r["robot"], r["date"], str(r["axis"]))):
        w.writerow(r)
    write_text_atomic(path, buf.getvalue())


@dataclass
class SimulateSummary:
    logs: int = 0
    axes: int = 0
    wearing: int = 0
    wall_s: float = 0.0
    outdir: str = ""
    extra: dict = field(default_factory=dict)


def simulate_fleet(cfg: FleetSimConfig, outdir: str | Path, workers: int | None = None,
                   scheduler: str | None = None, progress=None, client: Any = None) -> SimulateSummary:
    """Simulate the fleet into ``outdir`` (one Dask task per robot); write manifest and truth last.

    Parameters
    ----------
    cfg : what to simulate.   outdir : the output folder (created).
    workers, scheduler : see :func:`kukaid.fleet.run.open_client`.
    progress : called with (robots done, robots).
    client : a Dask client to use instead of opening one.
    """
    import contextlib
    import time

    from dask.distributed import as_completed

    from kukaid.atomic import write_text_atomic
    from kukaid.fleet.run import open_client

    t0 = time.perf_counter()
    out = Path(outdir).resolve()
    out.mkdir(parents=True, exist_ok=True)
    truth = draw_fleet(cfg)
    traj = arm_trajectory() if cfg.whole_arm else None
    rows: list[dict] = []
    with contextlib.ExitStack() as stack:
        if client is None:
            client = stack.enter_context(open_client(workers, scheduler))
        futs = [client.submit(simulate_robot, r, truth, str(out), traj, pure=False) for r in cfg.robot_names()]
        if progress is not None:
            progress(0, len(futs))
        for k, f in enumerate(as_completed(futs), start=1):
            rows += f.result()
            if progress is not None:
                progress(k, len(futs))
    write_text_atomic(out / "truth.json", json.dumps(truth, indent=1) + "\n")
    write_manifest(out / "manifest.csv", rows)
    return SimulateSummary(logs=len(rows), axes=len(truth["axes"]), wearing=sum(a["wearing"] for a in truth["axes"]),
                           wall_s=time.perf_counter() - t0, outdir=str(out))
