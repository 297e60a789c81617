"""Capture: run a trajectory on a robot and record an axis log, incrementally.

A capture source has a ``name`` and a ``capture(output, progress, stop)`` method that writes the
HDF5 axis log at ``output`` and returns a :class:`CaptureResult`.  Two sources:

:class:`SimCapture`
    The virtual KR C4 as a :class:`kukaid.robot.SimRobot` running the trajectory as its program;
    its cycles (``chunk`` seconds of simulated time each) are appended to the log with
    :class:`~kukaid.logs.writer.AxisLogWriter` and flushed, so a capture that is interrupted
    (Ctrl-C, SIGTERM, a killed process) leaves a readable log of everything recorded up to the
    last chunk.  The log carries the truth of the simulation (``truth``), the seed, the
    experiment kind, the trajectory's parameters and the simulator configuration.
:class:`KvpCapture`
    A real (or virtual) KR C4 over KUKAVARPROXY running its own KRL program: recorded by
    ``kukaid.krc.kvp_capture.capture_kvp`` (polling, or the KRL ring-buffer logger that keeps
    every 12 ms sample, which a command cycle over the network cannot guarantee).

:func:`capture` refuses to replace an existing log unless ``force`` (nothing recorded is lost); with
``force`` the new log is recorded beside the old one and replaces it only when the capture has ended.
"""
from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Protocol

import numpy as np

from kukaid import __version__
from kukaid.errors import KukaidError, OptionError

Progress = Callable[[float], None]


#: the largest |q - q_cmd| a simulated capture records without a warning, rad (1 degree; the virtual KR C4 follows
#: the excitations within 0.07 degree, and a real KR C4's following-error monitor stops the robot long before the
#: axis falls: the simulator does not)
FOLLOWING_WARN = math.radians(1.0)


@dataclass
class CaptureResult:
    """What a capture recorded: ``n_samples`` samples over ``duration`` s into ``output``.

    ``complete`` is False when the capture stopped early (the log then holds what was recorded
    until then); ``info`` holds backend-specific figures (rates, latencies, ...).
    """

    output: Path
    n_samples: int
    duration: float
    complete: bool = True
    info: dict[str, Any] = field(default_factory=dict)


class CaptureSource(Protocol):
    """Interface of a capture source."""

    name: str

    def total(self) -> float | None:
        """Expected duration of the capture, s (for a progress bar), or None if open-ended."""

    def capture(self, output: Path, progress: Progress | None = None,
                stop: threading.Event | None = None) -> CaptureResult:
        """Record the log into ``output`` (created or replaced); flush as it goes; end early,
        keeping what was recorded, when ``stop`` is set."""


def capture(backend: CaptureSource, output: str | Path, force: bool = False, progress: Progress | None = None,
            stop: threading.Event | None = None) -> CaptureResult:
    """Run ``backend`` into ``output``; refuse to replace an existing file unless ``force``.

    ``stop`` (a threading.Event, e.g. set by a SIGINT handler) ends the capture cleanly: the log
    keeps everything recorded and the result has ``complete=False``.
    """
    output = Path(output)
    if output.suffix.lower() not in (".h5", ".hdf5"):
        raise OptionError(f"{output}: a capture writes an HDF5 axis log; name it .h5 or .hdf5 "
                          f"(convert with `kukaid load LOG.h5 -o LOG.csv`)")
    if output.exists() and not force:
        raise KukaidError(f"{output}: already exists; choose another name or pass --force to replace it")
    if output.exists() and output.is_dir():
        raise KukaidError(f"{output}: is a directory")
    if not output.exists():
        return backend.capture(output, progress, stop)
    # --force over an earlier log: recorded beside it, and put in its place when the capture has
    # ended (cut short too: a record, as --force asked); one that fails or is killed leaves it as it was
    partial = output.with_name(f"{output.stem}.partial{output.suffix}")
    if partial.exists() or partial.is_symlink():
        raise KukaidError(f"{partial}: the record of an earlier capture that did not finish is in the way; move it "
                          "away or remove it, then capture again")
    try:
        result = backend.capture(partial, progress, stop)
    except (KukaidError, KeyboardInterrupt) as e:
        if not partial.exists():
            raise
        msg = str(e) if isinstance(e, KukaidError) else "capture interrupted"
        kept = "" if str(partial) in msg else f"; the samples recorded are kept in {partial}"
        err = KukaidError(f"{msg}{kept} ({output} is not changed)")
        err.exit_code = e.exit_code if isinstance(e, KukaidError) else 130
        raise err from None
    if result.n_samples == 0:  # nothing recorded: nothing to put in place
        partial.unlink(missing_ok=True)
        return CaptureResult(output=output, n_samples=0, duration=0.0, complete=result.complete, info=result.info)
    partial.replace(output)
    return CaptureResult(output=output, n_samples=result.n_samples, duration=result.duration,
                         complete=result.complete, info={**result.info, "output": str(output)})


class SimCapture:
    """Capture a trajectory on the virtual KR C4.

    Parameters
    ----------
    traj : trajectory (``.t`` s, ``.q`` rad, ``.axis``, ``.kind``, ``.params``), or a trajectory of
        several axes (``.axes``, ``.q`` (N, A), ``.robot``; from ``kukaid excite fourier``), run on
        the six-axis virtual KR C4 (:class:`kukaid.sim.robot_plant.VirtualRobotKRC4`).
    config : :class:`kukaid.sim.SimConfig` (default: the paper's A3), or for a trajectory of several
        axes a :class:`kukaid.sim.robot_plant.RobotSimConfig` (default: the trajectory's robot).
    seed : seed of the simulator's random streams.
    chunk : simulated seconds per appended block (1 to 2 s keeps an interrupted log current).
    settle : simulated seconds recorded after the end of the trajectory.
    extra_attrs : more attributes for the log (e.g. the effects requested on the command line).
    """

    name = "sim"

    def __init__(self, traj: Any, config: Any = None, seed: int = 0, chunk: float = 1.5, settle: float = 0.5,
                 extra_attrs: dict[str, Any] | None = None) -> None:
        from kukaid.sim import SimConfig
        from kukaid.sim.robot_plant import RobotSimConfig

        if not (isinstance(chunk, (int, float)) and math.isfinite(chunk) and chunk > 0):
            raise KukaidError(f"capture: chunk must be a positive number of seconds, got {chunk!r}")
        if not (isinstance(settle, (int, float)) and math.isfinite(settle) and settle >= 0):
            raise KukaidError(f"capture: settle must be >= 0 s, got {settle!r}")
        self.traj = traj
        self.robot = hasattr(traj, "axes")
        if config is None:
            config = RobotSimConfig(robot=traj.robot or RobotSimConfig.robot) if self.robot else SimConfig()
        self.config = config
        self.seed = int(seed)
        self.chunk = float(chunk)
        self.settle = float(settle)
        self.extra_attrs = dict(extra_attrs or {})

    def total(self) -> float:
        t = np.asarray(self.traj.t, dtype=float)
        return float(t[-1] - t[0]) + self.settle

    def attrs(self, sim: Any) -> dict[str, Any]:
        attrs = sim.log_attrs(self.traj)
        attrs.update(backend="sim", capture_chunk=self.chunk, capture_settle=self.settle,
                     kukaid_version=__version__)
        attrs.setdefault("experiment", str(getattr(self.traj, "kind", "unknown")))
        limits = getattr(self.traj, "limits", None)
        if limits:
            attrs["trajectory_limits"] = limits
        attrs.update(self.extra_attrs)
        return attrs

    def capture(self, output: Path, progress: Progress | None = None,
                stop: threading.Event | None = None) -> CaptureResult:
        from kukaid.logs import AxisLogWriter
        from kukaid.robot import SimRobot
        from kukaid.sim import VirtualKRC4
        from kukaid.sim.robot_plant import VirtualRobotKRC4

        if self.robot:
            sim = VirtualRobotKRC4(self.config, seed=self.seed)
            axes = sim.axes
            robot = SimRobot(sim, sim.start_position(self.traj), program=self.traj)
        else:
            axis = int(getattr(self.traj, "axis", self.config.axis))
            axes = (axis,)
            q = np.asarray(self.traj.q, dtype=float)
            robot = SimRobot(VirtualKRC4(self.config, seed=self.seed, axis=axis), float(q[0]), program=self.traj)
        total = self.total()
        n_chunks = max(1, int(math.ceil(total / self.chunk - 1e-9)))
        writer = None
        n = 0
        t_last = 0.0
        complete = True
        done = 0.0
        follow = 0.0  # the largest |q - q_cmd|, rad
        try:
            for k in range(n_chunks):
                if stop is not None and stop.is_set():
                    complete = False
                    break
                end = min(total, (k + 1) * self.chunk)
                if k == 0:  # the robot starts with its first sample, then runs to the chunk's end
                    first = robot.start().channels
                    done = self.config.sample_time
                    more = robot.cycle(None, max(end - done, 0.0)).channels
                    b = {c: np.concatenate([first[c], more[c]]) for c in first}
                else:
                    b = robot.cycle(None, end - done).channels
                done = max(end, done)
                if writer is None:
                    channels = [c for c in ("q", "tau", "q_cmd", "temp", "tau_ext_true") if c in b]
                    writer = AxisLogWriter(output, axes=axes, channels=channels, attrs=self.attrs(robot.sim),
                                           flush_every=10**9)
                if b["time"].size:
                    writer.append(b["time"], **{c: b[c] for c in writer.channels})
                    n += int(b["time"].size)
                    t_last = float(b["time"][-1])
                    if "q_cmd" in b:
                        follow = max(follow, float(np.max(np.abs(np.asarray(b["q"]) - np.asarray(b["q_cmd"])))))
                writer.flush()
                if progress is not None:
                    progress(done)
        finally:
            if writer is not None:
                writer.close()
        return CaptureResult(output=output, n_samples=n, duration=t_last, complete=complete,
                             info={"seed": self.seed, "chunks": n_chunks, "simulated_s": done,
                                   "following_error_max": follow})


class KvpCapture:
    """Capture from a KR C4 over KUKAVARPROXY (``kukaid.krc.kvp_capture.capture_kvp``)."""

    name = "kvp"

    def __init__(self, host: str = "127.0.0.1", port: int = 7000, axes: Iterable[int] = (3,),
                 duration: float | None = None, until_interrupt: bool = False, mode: str = "poll",
                 attrs: dict[str, Any] | None = None) -> None:
        self.host, self.port = host, int(port)
        self.axes = tuple(int(a) for a in axes)
        self.duration, self.until_interrupt, self.mode = duration, bool(until_interrupt), mode
        self.extra_attrs = dict(attrs or {})
        if duration is None and not until_interrupt:
            raise OptionError("capture: the kvp backend needs --duration S or --until-interrupt")

    def total(self) -> float | None:
        return None if self.until_interrupt and self.duration is None else self.duration

    def capture(self, output: Path, progress: Progress | None = None,
                stop: threading.Event | None = None) -> CaptureResult:
        capture_kvp = load_kvp_capture()
        info = capture_kvp(output, self.host, self.port, self.axes, self.duration, self.until_interrupt,
                           self.mode, progress, attrs=self.extra_attrs or None, stop_event=stop)
        info = dict(info or {})
        # complete: the duration ran out, or an interrupt ended --until-interrupt (its normal end)
        why = info.get("stopped_by")
        complete = why == "duration" or (self.until_interrupt and why in ("signal", "stop-event"))
        return CaptureResult(output=Path(info.get("output", output)), n_samples=int(info.get("n_samples", 0)),
                             duration=float(info.get("duration_s", 0.0)), complete=complete, info=info)


def load_kvp_capture() -> Callable[..., dict]:
    """``kukaid.krc.kvp_capture.capture_kvp``, or a clear error if that module is not available."""
    try:
        from kukaid.krc.kvp_capture import capture_kvp
    except ModuleNotFoundError as e:
        if e.name in ("kukaid.krc.kvp_capture",):
            raise KukaidError("capture: the kvp backend is not available in this installation "
                              "(module kukaid.krc.kvp_capture is missing)") from None
        raise
    return capture_kvp


def sim_config(path: str | Path | None = None, noise: float | None = None,
               effects: Iterable[tuple[str, float | None]] = (), seed: int = 0,
               size_range: tuple[float, float] = (2.0, 5.0)) -> tuple[Any, dict[str, Any]]:
    """Simulator configuration from a JSON file, a noise level and hidden effects.

    Parameters
    ----------
    path : JSON overrides of the simulator configuration (None: the paper's defaults).
    noise : torque noise sigma, N·m (None: keep the configuration's).
    effects : (name, size in N·m or None) pairs; parameters drawn with
        :func:`kukaid.sim.effects.draw_effect` from a generator seeded by ``seed``.  A missing
        size is drawn uniformly from ``size_range`` times the torque noise sigma (2 to 5 sigma:
        1 to 2.5 N·m at the default 0.5 N·m; sigma 0.5 N·m is used when the noise is off).
    seed : the capture's seed (effect parameters use their own stream derived from it).

    Returns
    -------
    (SimConfig, attrs) where attrs records the requested effects for the log.
    """
    from kukaid.sim import SimConfig, draw_effect, load_sim_config

    cfg = load_sim_config(path) if path is not None else SimConfig()
    attrs: dict[str, Any] = {}
    if noise is not None:
        if not (math.isfinite(noise) and noise >= 0):
            raise OptionError(f"capture: --noise must be a number >= 0 N·m, got {noise}")
        cfg = cfg.replace(noise_sigma=float(noise))
    effects = list(effects)
    if effects:
        rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0xEFFEC7]))
        eff = dict(cfg.effects)
        requested = []
        sigma = cfg.noise_sigma if cfg.noise_sigma > 0 else 0.5
        for name, size in effects:
            s = float(rng.uniform(*size_range)) * sigma if size is None else float(size)
            eff[name] = draw_effect(name, s, rng, mx=cfg.Mx)
            requested.append({"name": name, "size": s})
        cfg = cfg.replace(effects=eff)
        attrs["effects_requested"] = requested
    return cfg, attrs


def robot_sim_config(path: str | Path | None = None, robot: str = "") -> Any:
    """The six-axis simulator's configuration: JSON overrides (``RobotSimConfig`` fields) of the
    defaults, for ``robot`` (the trajectory's) unless the file names one."""
    from kukaid.sim.robot_plant import RobotSimConfig

    cfg = RobotSimConfig.load(path) if path is not None else RobotSimConfig()
    if robot and (path is None or cfg.robot == RobotSimConfig.robot):
        cfg = cfg.replace(robot=robot)
    if path is not None and cfg.coupling is not None:  # its size is the robot's: the file is named
        from kukaid.models.urdf import load_model

        cfg.coupling_matrix(load_model(cfg.robot).nv, str(path))
    return cfg


def check_limits(traj: Any, where: str = "trajectory") -> None:
    """Refuse a trajectory that breaks its axis limits (those stored in it, else the robot's).

    A real KR C4 would refuse it too; the limits stored by ``kukaid excite`` (``traj.limits``)
    take precedence over the built-in KR 6 R700 sixx figures.
    """
    from kukaid.errors import LimitError
    from kukaid.models.limits import AxisLimits

    if hasattr(traj, "axes"):  # several axes: the limits excite stored per axis, else the URDF's
        from kukaid.excite.fourier import robot_limits
        from kukaid.models.urdf import load_model

        try:
            robot = traj.robot or "kr6-r700-sixx"
            traj.check(None if traj.limits else robot_limits(load_model(robot), robot=robot))
        except LimitError as e:
            raise LimitError(f"{where}: {e}") from None
        return

    if getattr(traj, "limits", None):
        limits = AxisLimits.from_dict(traj.limits, where=f"{where}: field 'limits'")
    elif 1 <= int(getattr(traj, "axis", 3)) <= 6:
        limits = AxisLimits.kr6_r700_sixx(int(getattr(traj, "axis", 3)))
    else:
        return
    try:
        limits.check(traj)
    except LimitError as e:
        raise LimitError(f"{where}: {e}") from None


def simulated_range(axis: int) -> tuple[float, float, str]:
    """The range of motion (rad) of the virtual KR C4's axis ``axis``, a KR 6 R700 sixx's (the simulator has
    no hard stops: beyond them it simulates no robot), and how to name it."""
    from kukaid.models.limits import AxisLimits

    rng = AxisLimits.kr6_r700_sixx(axis)
    return rng.q_min, rng.q_max, (f"the range of motion of the virtual KR C4's A{axis} (a KR 6 R700 sixx), "
                                  f"{math.degrees(rng.q_min):.4g} to {math.degrees(rng.q_max):.4g} degrees")


def check_simulated_range(traj: Any, where: str = "trajectory") -> None:
    """Refuse a one-axis trajectory beyond :func:`simulated_range`: the simulator would record a robot
    that is not there (``excite --q-max-deg`` may describe another, real robot; the sim runs this one)."""
    from kukaid.errors import LimitError

    axis = int(getattr(traj, "axis", 3))
    if hasattr(traj, "axes") or not 1 <= axis <= 6 or getattr(traj, "joint", "revolute") == "prismatic":
        return
    q_min, q_max, text = simulated_range(axis)
    lo, hi = float(np.min(traj.q)), float(np.max(traj.q))
    if lo < q_min - 1e-9 or hi > q_max + 1e-9:
        raise LimitError(f"{where}: reaches {math.degrees(lo):.4g} to {math.degrees(hi):.4g} degrees, beyond {text}: "
                         "the simulator has no robot there; excite within it, or capture on the robot the trajectory "
                         "is for (--backend kvp)")


def parse_effect(spec: str) -> tuple[str, float | None]:
    """``NAME`` or ``NAME=SIZE`` (SIZE in N·m) -> (name, size or None); clear error otherwise."""
    from kukaid.sim import EFFECTS

    name, _, size = spec.partition("=")
    name = name.strip()
    if name not in EFFECTS:
        raise OptionError(f"--effect {spec}: unknown effect '{name}' (known: {', '.join(EFFECTS)})")
    if not _:
        return name, None
    try:
        s = float(size)
    except ValueError:
        raise OptionError(f"--effect {spec}: size '{size}' is not a number (N·m)") from None
    if not (math.isfinite(s) and s >= 0):
        raise OptionError(f"--effect {spec}: size must be a number >= 0 N·m")
    return name, s
