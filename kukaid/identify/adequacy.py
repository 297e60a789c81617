"""Is the single-axis model adequate for a log?  Checks a fit reports instead of failing silently.

* :func:`raw_noise_sigma`: the torque-noise level of the raw samples (second differences, MAD);
  :func:`noise_floor`: the RMS a perfect model would leave after the fit's zero-phase filter.
* :func:`moving_axes`: the other axes of a log that move (their motion changes the gravity and
  inertia torque a multi-body robot puts on this axis, which the single-axis model cannot hold).
* :func:`assess`: warnings (one line each) from the solver status, the parameters on their
  bounds, the residual against the noise floor and the other axes' motion, with what to do.
* :func:`check_not_held`: a log whose samples are held (each controller sample recorded many
  times, as a KUKAVARPROXY poll faster than the controller's 12 ms / 4 ms cycle did) is refused:
  its sample rate sets the filter and the differences, and the fit on it is wrong.
* :func:`role_warnings`: a log whose ``experiment`` attribute (written by capture from the
  trajectory) is not the role it was given in (``--friction``, ``--inertia``, ``--presliding``).
* :func:`unit_warnings`: a revolute axis that moves over under 2 degrees (radians under a degree header).
"""
from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

_MAD = 1.482602218505602  # MAD -> standard deviation for a normal distribution

#: an axis "moves" when its position range exceeds this (rad, or m for a prismatic axis)
MOVE_RANGE = 0.02
#: a fit residual above this many noise floors is "far above noise"
FAR_ABOVE_NOISE = 5.0
#: share of samples identical to the one before (every position and torque) from which a log is
#: "held": a measured torque carries noise, so even a standing axis repeats exactly only rarely;
#: a controller sample polled twice already makes 50 %
HELD_SHARE = 0.2
#: the shortest sample time a KR C4 delivers over KUKAVARPROXY (its fastest interpolation cycle), s
KRC_MIN_SAMPLE_TIME = 0.004
#: experiments of the trajectories (``kukaid excite KIND``) that have a role of their own in ``fit``
ROLES = ("friction", "inertia", "presliding")


#: correlation of a torque's successive second differences above which the torque is smooth sample
#: to sample (white noise gives -2/3, the virtual KR C4's quantised noisy torque -0.15, EMPS 0.08;
#: the LWR4+'s torques, filtered before they were recorded, 0.999)
SMOOTH_D2_CORRELATION = 0.5


def raw_noise_sigma(x: np.ndarray) -> float:
    """Standard deviation of white noise on the samples ``x`` (same unit as x).

    Uses the second difference d2 = x[k+1] - 2 x[k] + x[k-1], var(d2) = 6 sigma² for white
    noise, with a robust (MAD) scale; falls back to a trimmed RMS when more than half the second
    differences are exactly equal (coarse quantisation).
    """
    x = np.asarray(x, dtype=float)
    if x.size < 5:
        return 0.0
    d2 = np.diff(x, 2)
    med = np.median(d2)
    mad = np.median(np.abs(d2 - med))
    if mad > 0:
        return float(_MAD * mad / np.sqrt(6.0))
    a = np.sort(np.abs(d2 - med))
    a = a[: max(1, int(0.95 * a.size))]
    return float(np.sqrt(np.mean(a * a) / 6.0))


def smooth_at_source(x: np.ndarray) -> bool:
    """Whether the samples ``x`` were low-pass filtered before they were recorded (successive second
    differences correlated above :data:`SMOOTH_D2_CORRELATION`), or interpolated to a finer rate
    (:func:`interpolated`): what noise they carry is then not white, and :func:`raw_noise_sigma`
    does not measure it (it sees almost nothing)."""
    d2 = np.diff(np.asarray(x, dtype=float), 2)
    if interpolated(d2):
        return True
    d2 = d2 - d2.mean() if d2.size else d2
    den = float(d2 @ d2)
    return d2.size > 2 and den > 0 and float(d2[:-1] @ d2[1:]) / den > SMOOTH_D2_CORRELATION


def interpolated(d2: np.ndarray, longest: int = 16) -> bool:
    """Whether the second differences ``d2`` are those of samples interpolated linearly to a finer rate
    (MATLAB's ``interp1`` of a 12 ms log to 4 ms): between the recorded samples they vanish to rounding
    (a noise read from them: 1e-13 N·m, a model "6e12 x the noise floor"), so what is left of them never
    falls on some phase of the pattern the rate ratio repeats with (2 to ``longest`` samples: 12 ms to
    4 ms, every third; to 8 ms, two of three).  A coarsely quantised signal has many zero second
    differences too, but its others fall on every phase."""
    d2 = np.abs(np.asarray(d2, dtype=float))
    big = np.flatnonzero(d2 > 1e-9 * max(float(d2.max(initial=0.0)), 1e-300))
    if big.size > 0.8 * d2.size:
        return False
    return any(np.bincount(big % p, minlength=p).min() < 0.05 * big.size / p
               for p in range(2, longest + 1) if big.size >= 20 * p)


def filter_noise_gain(fs: float, cutoff: float, order: int) -> float:
    """White-noise power gain of the zero-phase Butterworth low-pass (variance out / in)."""
    from kukaid.identify.filtering import lowpass

    n = 4096
    imp = np.zeros(n)
    imp[n // 2] = 1.0
    h = lowpass(imp, fs, cutoff, order)[0]
    return float(np.sum(h * h))


def noise_floor(preps: Sequence[Any]) -> float:
    """RMS residual of a perfect model on the filtered torque of prepared logs, N·m (pooled)."""
    num = den = 0.0
    for pr in preps:
        st = pr.settings
        g = filter_noise_gain(st["fs"], st["cutoff"], st["order"]) if st.get("filter_torque", True) else 1.0
        k = int(np.count_nonzero(pr.dynamic))
        num += raw_noise_sigma(pr.tau_span) ** 2 * g * k  # at the original rate: see Prepared
        den += k
    return float(math.sqrt(num / den)) if den else 0.0


def moving_axes(log: Any, axis: int, min_range: float = MOVE_RANGE) -> list[int]:
    """The other axes of ``log`` whose position range exceeds ``min_range`` (rad or m)."""
    out = []
    for k, a in enumerate(log.axes):
        if a != axis and float(np.ptp(np.asarray(log.q[:, k], dtype=float))) > min_range:
            out.append(int(a))
    return out


#: parameters whose bounds are the limits of an admissible shape, not of what the data could show: the
#: Stribeck exponent delta at 0.5 or 2 (the paper's range; its own fit ends at 2.0, as does the
#: simulator's default truth) is the steepest or flattest rise the model has, found by the data
SHAPE_LIMITS = ("delta",)


def assess(axis: int, residual_rms: float, floor: float, others: Sequence[int], at_bound: Sequence[dict],
           converged: bool, status: str) -> tuple[list[str], dict[str, Any]]:
    """Warnings for a single-axis fit, and the figures behind them (for the parameter file).

    ``at_bound``: ``{"name", "value", "bound", "side", "given"}``, ``given`` true for a bound the user gave;
    one of :data:`SHAPE_LIMITS` on its own limit is not warned as undetermined (the table lists it).
    Returns (warnings, {"residual_over_noise", "other_axes_moving", "single_axis_adequate"}).
    ``floor`` NaN: not known (a torque filtered before it was recorded, :func:`smooth_at_source`), so
    the residual is not judged against it (``residual_over_noise`` NaN).
    """
    ratio = residual_rms / floor if floor > 0 else math.nan if math.isnan(floor) else math.inf
    unknown = math.isnan(ratio)
    warnings = []
    if not converged:
        warnings.append(f"IPOPT stopped before converging ('{status}'); the best parameters it found are written "
                        "(never worse than the start)")
    def listed(bs: Sequence[dict]) -> str:
        return ", ".join(f"{b['name']} = {b['bound']:.4g} ({b['side']} bound)" for b in bs)  # on it, up to the solver

    # on a bound the data set: a shape at a limit of its admissible range (the table lists it) is a shape
    undetermined = [b for b in at_bound if not b.get("given") and b["name"] not in SHAPE_LIMITS]
    if undetermined:
        warnings.append(f"on a bound: {listed(undetermined)}: the data do not determine these, or the model does "
                        "not describe the data")
    if any(b.get("given") for b in at_bound):
        warnings.append(f"on the bound --bound gave: {listed([b for b in at_bound if b.get('given')])}: the value "
                        "is that bound, not an estimate (the data pull it past the bound, or do not determine it)")
    inadequate = bool(others) and (unknown or ratio > FAR_ABOVE_NOISE or bool(undetermined) or not converged)
    if inadequate:
        warnings.append(
            f"the single-axis model cannot explain A{axis}: other axes ({', '.join(f'A{a}' for a in others)}) move "
            f"in the log, so the gravity and inertia torque on A{axis} depend on their positions ("
            + (f"{UNKNOWN_FLOOR}, so the residual cannot show otherwise" if unknown else
               f"residual {ratio:.3g} x the noise floor")
            + f"). Fit all axes together with a robot model (kukaid fit --robot URDF), "
            f"or record A{axis} moving alone; treat these parameters as a local description only")
    elif unknown:
        warnings.append(f"{UNKNOWN_FLOOR}: whether the model misses an effect is not judged from the residual")
    elif ratio > FAR_ABOVE_NOISE:
        warnings.append(_residual_warning(ratio))
    figures = {"residual_over_noise": ratio, "other_axes_moving": list(others), "single_axis_adequate": not inadequate}
    return warnings, figures


#: why a fit's noise floor is not known
UNKNOWN_FLOOR = ("the noise floor is not known: the torque was filtered or resampled before it was recorded (its "
                 "noise is not white)")


def _residual_warning(ratio: float) -> str:
    return f"residual {ratio:.3g} x the noise floor: the model misses an effect (run kukaid diagnose)"


#: metrics a file diagnose refined keeps as the fit wrote them: what the fit said about the data and
#: the model's form (and the Maxwell-slip elements, which diagnose leaves as they are)
OF_THE_DATA = ("warnings", "other_axes_moving", "single_axis_adequate", "friction_model_choice",
               "maxwell_slip_rms", "maxwell_slip_sum_W", "maxwell_slip_samples")


def with_effects(metrics: dict, added: Sequence[str], rmse_before: float, rmse_after: float, floor: float) -> dict:
    """The ``metrics`` of the file diagnose writes with the effects ``added``.

    The fit's figures of its model (MSEs, condition numbers, correlation matrix, parameters on a
    bound, the residual correlation factor its white-residual standard deviations needed) are of the
    model without the effects: they move, as the fit wrote them, under ``original_fit`` (a file
    refined twice keeps the fit's).  In their place diagnose's figures of the refined model on the
    logs it was given: ``torque_rmse`` (``torque_rmse_before``: the file's model before), N·m (N),
    ``noise_floor``, ``residual_over_noise`` (NaN: the floor not known) and ``std_note`` (its
    standard deviations are HAC).  What the fit said about the data stays (:data:`OF_THE_DATA`);
    its residual warning was of the model without the effects, so it goes, and while the gap is still
    far above the noise a warning says both figures."""
    fit = metrics.get("original_fit") or {k: v for k, v in metrics.items() if k not in OF_THE_DATA}
    ratio = rmse_after / floor if floor > 0 else math.nan
    out = {k: v for k, v in metrics.items() if k in OF_THE_DATA}
    out.update(torque_rmse=rmse_after, torque_rmse_before=rmse_before, noise_floor=floor, residual_over_noise=ratio,
               std_note="HAC standard deviations of diagnose's refit with the effects (the residuals' correlation "
                        "accounted for: no correlation factor applies)", original_fit=fit)
    r_fit = fit.get("residual_over_noise")
    if isinstance(r_fit, (int, float)) and math.isfinite(r_fit):  # the fit's residual warning, or an earlier diagnose's
        stale = _residual_warning(r_fit).split(":")[0]
        out["warnings"] = [w for w in out.get("warnings", []) if not w.startswith(stale)]
        if ratio > FAR_ABOVE_NOISE:
            out["warnings"].append(f"{stale} in the fit; with the effects diagnose added ({', '.join(added)}) "
                                   f"{rmse_before / floor:.3g} -> {ratio:.3g} x its noise floor: the model still "
                                   "misses an effect (run kukaid diagnose)")
    return out


def held_share(log: Any) -> float:
    """Share of a log's samples identical to the one before in every position and torque (0 for a
    log in which no position changes at all: a standstill, which is not a question of sampling)."""
    q = np.asarray(log.q, dtype=float).reshape(len(log.time), -1)
    tau = np.asarray(log.tau, dtype=float).reshape(len(log.time), -1)
    if q.shape[0] < 3 or not np.any(np.ptp(q, axis=0) > 0):
        return 0.0  # nothing moves: not held, a standstill (the fit says it has no dynamic samples)
    same = np.all(q[1:] == q[:-1], axis=1) & np.all(tau[1:] == tau[:-1], axis=1)
    return float(np.mean(same))


def check_not_held(log: Any, name: str | None = None) -> None:
    """Refuse (:class:`~kukaid.errors.FitError`) a log whose samples are held.

    Held: at least :data:`HELD_SHARE` of the samples repeat the one before exactly, or a
    KUKAVARPROXY capture (attribute ``source``) sampled faster than the controller can deliver
    (:data:`KRC_MIN_SAMPLE_TIME`, with a margin).  Such a log (``kukaid capture --backend kvp
    --mode poll`` of kukaid 0.x polled each 12 ms sample about 100 times) makes the fit choose its
    filter from the inflated rate and difference steps of a staircase: parameters off by orders of
    magnitude, with no sign of it but the residual."""
    from kukaid.errors import FitError

    name = name or str(log.attrs.get("source_file", "log"))
    t = np.asarray(log.time, dtype=float)
    if t.size < 3:
        return
    share = held_share(log)
    dt = float(np.median(np.diff(t)))
    kvp = str(log.attrs.get("source", "")) == "kukavarproxy"
    fast = kvp and dt < 0.75 * KRC_MIN_SAMPLE_TIME
    if share < HELD_SHARE and not fast:
        return
    rate = f"{1.0 / dt:.0f} Hz" if dt > 0 else "no time between samples"
    raise FitError(
        f"{name}: {share:.0%} of the samples repeat the one before exactly ({rate}; a KR C4 gives a new sample "
        f"every 12 ms, 4 ms at the fastest): the controller's samples are held, recorded many times over, and a "
        f"fit on them is wrong. Capture it again with `kukaid capture --backend kvp --mode ring` (exact 12 ms "
        f"samples from the KRL logger, `kukaid krl-logger`) or with the poll mode of this version, which keeps "
        f"each controller sample once")


def pushed_log_warnings(log: Any, name: str | None = None) -> list[str]:
    """A warning when ``log`` is a run log of ``kukaid run-admittance`` (attribute ``experiment``
    'admittance'): its torque holds the push of the person guiding the axis, which no model of the
    axis predicts (a fit takes the push for friction and inertia, a validation or a diagnosis
    reports it as the model's error: the demo's run validated at 32 % relative error)."""
    exp = log.attrs.get("experiment") if hasattr(log, "attrs") else None
    if exp != "admittance":
        return []
    name = name or str(log.attrs.get("source_file", "log"))
    return [f"{name} is a run log of kukaid run-admittance: its torque holds the push of the person guiding the "
            "axis, which no model of the axis predicts; use a log recorded with nobody touching the robot "
            "(kukaid capture)"]


def run_logs_only(names: list[str]) -> FitError:
    """The error of a fit given only run logs of ``kukaid run-admittance`` (``names``): hand guiding,
    not an excitation; whatever of the fit failed first (one direction of motion) is beside the point."""
    from kukaid.errors import FitError

    what, its = ("is a run log", "not an excitation log: its") if len(names) == 1 else \
        ("are run logs", "not excitation logs: their")
    return FitError(f"{', '.join(names)}: {what} of kukaid run-admittance (hand guiding), {its} torque holds "
                    "the push of the person guiding the axis, which no model of the axis predicts; "
                    "fit logs of an excitation recorded with nobody touching the robot (kukaid excite, then kukaid "
                    "capture)")


#: a revolute axis moving over less than this (rad: 2 degrees) in a log fitted for its friction and
#: inertia looks like positions in radians read as degrees (57 x too small)
MIN_MOTION = math.radians(2.0)


def unit_warnings(log: Any, axis: int, name: str | None = None) -> list[str]:
    """A warning when revolute axis ``axis`` of ``log`` moves over less than :data:`MIN_MOTION` in all:
    radians written under a degree header (the reader's ``position_columns`` names it) read 57 x too
    small, and so do the speeds, while Izz and Fv come out 57 x too large, with no other sign.  A
    warning, never a refusal: an axis can move that little; none for a log that records the pre-sliding
    experiment (attribute ``experiment``), which moves that little by design."""
    k = log.index(axis)
    span = float(np.ptp(np.asarray(log.q[:, k], dtype=float)))
    if log.joint[k] != "revolute" or span >= MIN_MOTION or log.attrs.get("experiment") == "presliding":
        return []  # the pre-sliding experiment (the log says it records it) moves a fraction of a degree
    name = name or str(log.attrs.get("source_file", "log"))
    col = (log.attrs.get("position_columns") or {}).get(str(axis))
    col = f"column {col}" if col else f"the position of A{axis}"
    return [f"{name}: {col} spans only {math.degrees(span):.3g} degrees over the whole log, too little to fit "
            "friction and inertia: radians written under a degree header? (read as degrees, positions and speeds "
            "are 57 x too small, Izz and Fv 57 x too large)"]


def role_warnings(log: Any, role: str, name: str | None = None, command: str = "fit") -> list[str]:
    """A warning when ``log`` records (attribute ``experiment``) an experiment other than ``role``,
    given to ``command`` ("fit" or "report").

    Logs without the attribute (imported from CSV, MAT, KUKA Trace) give none."""
    exp = log.attrs.get("experiment") if hasattr(log, "attrs") else None
    if not isinstance(exp, str) or not exp or exp == role:
        return []
    name = name or str(log.attrs.get("source_file", "log"))
    if exp in ROLES:
        fix = f"give it as --{exp}"
    elif command == "report":
        fix = f"give it as --log {name}, or the {role} experiment's log as --{role}"
    else:
        fix = f"give it as a general log (kukaid fit {name} ...), or the {role} experiment's log as --{role}"
    harm = ("the parameters are fitted on the wrong data and worse than they should be" if command == "fit" else
            f"the {role.replace('presliding', 'pre-sliding')} page is drawn from the wrong data")
    return [f"{name} was given as --{role} but records the '{exp}' experiment (attribute 'experiment'): {harm}; {fix}"]
