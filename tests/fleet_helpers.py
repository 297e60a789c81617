"""Small simulated fleets for the fleet tests (written in-process, without a Dask cluster), and a
fleet folder with faulty logs: truncated HDF5, empty CSV, NaNs, a log of another axis, a duplicate."""
from __future__ import annotations

import csv
import shutil
import subprocess
import sys
import time
from pathlib import Path

from kukaid.fleet.simulate import FleetSimConfig, arm_trajectory, draw_fleet, simulate_robot, write_manifest


def small_fleet(out: Path, robots: int = 3, days: int = 4, seed: int = 5, axes=(3,), wear_share: float = 0.0,
                whole_arm: bool = False) -> Path:
    """A simulated fleet under ``out`` (manifest.csv, truth.json, logs/); returns the manifest.
    ``whole_arm``: one six-axis log of the KR 6 R700 sixx per robot and day (``axis`` empty)."""
    import json

    cfg = FleetSimConfig(robots=robots, days=days, seed=seed, axes=tuple(axes), wear_share=wear_share,
                         whole_arm=whole_arm)
    truth = draw_fleet(cfg)
    traj = arm_trajectory() if whole_arm else None
    rows = []
    for r in cfg.robot_names():
        rows += simulate_robot(r, truth, str(out), traj)
    (out / "truth.json").write_text(json.dumps(truth))
    write_manifest(out / "manifest.csv", rows)
    return out / "manifest.csv"


def fault_fleet(out: Path) -> tuple[Path, dict[str, str]]:
    """A fleet of 3 robots x 3 days of A3 logs plus faulty entries; returns the manifest and
    {path in the manifest: the phrase its error row must contain} of the faulty ones."""
    import numpy as np

    from kukaid.logs import read_log, write_csv

    small_fleet(out, robots=3, days=3, seed=11)
    with open(out / "manifest.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    good = out / rows[0]["path"]
    bad = out / "bad"
    bad.mkdir()
    # truncated HDF5: a good log cut in half
    data = good.read_bytes()
    (bad / "truncated.h5").write_bytes(data[: len(data) // 2])
    # empty CSV
    (bad / "empty.csv").write_text("")
    # NaNs: a good log as CSV with one torque sample not a number
    write_csv(read_log(good), bad / "nan.csv")
    lines = (bad / "nan.csv").read_text().splitlines()
    cells = lines[40].split(",")
    cells[2] = "nan"
    lines[40] = ",".join(cells)
    (bad / "nan.csv").write_text("\n".join(lines) + "\n")
    # a log of another axis (A2) where the manifest says A3
    other = out / "other"
    small_fleet(other, robots=1, days=1, seed=12, axes=(2,))
    shutil.copy(next((other / "logs").rglob("*.h5")), bad / "axis2.h5")
    # a duplicate: the same bytes as a good log under another name
    shutil.copy(good, bad / "copy.h5")
    extra = [("R901", "3", "2026-01-05", "bad/truncated.h5"), ("R902", "3", "2026-01-05", "bad/empty.csv"),
             ("R903", "3", "2026-01-05", "bad/nan.csv"), ("R904", "3", "2026-01-05", "bad/axis2.h5"),
             ("R905", "3", "2026-01-05", "bad/copy.h5"), ("R906", "3", "2026-01-05", "bad/missing.h5")]
    with open(out / "manifest.csv", "a", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        for e in extra:
            w.writerow(e)
    expect = {"bad/truncated.h5": "truncated", "bad/empty.csv": "empty", "bad/nan.csv": "not a finite number",
              "bad/axis2.h5": "not of A3", "bad/copy.h5": "duplicate", "bad/missing.h5": "no such file"}
    assert np.isfinite(1.0)
    return out / "manifest.csv", expect


def rippled_arm_log(path: Path, seed: int = 20) -> Path:
    """A 12 s six-axis log of the KR 6 R700 sixx (250 Hz, a seeded multi-sine, A2 about mid-range)
    whose A4 carries a position ripple the URDF does not know (0.3 N·m at order 11.3 rad/rad):
    ``kukaid diagnose`` of its own whole-arm fit names ``position_ripple@A4``. (It was a 5 N·m gas
    counterbalance on A2, 4 % of A2's gravity torque: named only while the spring's geometry was
    chosen on every sample, the held-out block's too; one recording's blocks do not carry a
    plausible one to the others well enough to name it.)"""
    import numpy as np

    from kukaid.logs import AxisLog, write_hdf5
    from kukaid.models.robot import RobotModel
    from robot_sim_helpers import multisine, true_friction, true_parameters

    kr6 = RobotModel("kr6-r700-sixx")
    pi, fr = true_parameters(kr6, 1), true_friction(6, 2)
    t, q, qd, qdd = multisine(kr6, 12.0, 250.0, seed=seed)
    mid = 0.5 * (kr6.lower[1] + kr6.upper[1])
    q[:, 1] = mid + 0.35 * (q[:, 1] - mid)
    qd[:, 1] *= 0.35
    qdd[:, 1] *= 0.35
    tau = np.einsum("sjk,k->sj", kr6.regressor(q, qd, qdd), pi) + fr["Fc"] * np.sign(qd) + fr["Fv"] * qd + fr["offset"]
    tau[:, 3] += 0.3 * np.sin(11.3 * q[:, 3] + 0.4)
    rng = np.random.default_rng(0)
    tau += 0.05 * rng.standard_normal(tau.shape)
    log = AxisLog(time=t, q=q + 1e-5 * rng.standard_normal(q.shape), tau=tau, axes=tuple(range(1, 7)), attrs={})
    path.parent.mkdir(parents=True, exist_ok=True)
    write_hdf5(log, path)
    return path


class DaskProcesses:
    """A ``dask scheduler`` and ``dask worker`` started as separate processes on 127.0.0.1 (the
    venv's dask), stopped by their own process ids on exit; ``address`` is the scheduler's."""

    def __init__(self, folder: Path, workers: int = 1, timeout: float = 60.0) -> None:
        self.folder, self.workers, self.timeout = folder, workers, timeout
        self.procs: list[subprocess.Popen] = []
        self.address = ""

    def __enter__(self) -> "DaskProcesses":
        import json

        dask = [str(Path(sys.executable).parent / "dask")]
        sfile = self.folder / "scheduler.json"
        log = open(self.folder / "dask.log", "w")
        self.procs.append(subprocess.Popen(dask + ["scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                                                   "--scheduler-file", str(sfile)],
                                           stdout=log, stderr=subprocess.STDOUT, cwd=self.folder))
        t_end = time.monotonic() + self.timeout
        while not sfile.exists() or not sfile.read_text().strip():
            if time.monotonic() > t_end or self.procs[0].poll() is not None:
                self.__exit__(None, None, None)
                raise RuntimeError("dask scheduler did not start: " + (self.folder / "dask.log").read_text()[-2000:])
            time.sleep(0.2)
        self.address = json.loads(sfile.read_text())["address"]
        worker = dask + ["worker", "--scheduler-file", str(sfile),
                  "--nworkers", str(self.workers), "--nthreads", "1", "--no-dashboard", "--host", "127.0.0.1"]
        self.procs.append(subprocess.Popen(worker, stdout=log, stderr=subprocess.STDOUT, cwd=self.folder))
        from dask.distributed import Client

        with Client(self.address, timeout=self.timeout) as c:
            c.wait_for_workers(self.workers, timeout=self.timeout)
        return self

    def __exit__(self, *exc) -> None:
        for p in reversed(self.procs):
            if p.poll() is None:
                p.terminate()
        for p in reversed(self.procs):
            try:
                p.wait(timeout=15)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(timeout=5)
