"""The ``kukaid fit`` flow: logs in, a ``kukaid.params/1`` parameter dictionary out.

Logs given by role are used as the paper uses those experiments:

* ``friction`` (constant-velocity sweeps): Stribeck friction, by the ``staged`` method
  (Γf = (Γ+ - Γ-)/2 at the same positions, eqs. 2-5) or the ``joint`` method (Stribeck and the
  rigid body fitted together on all dynamic samples, :func:`~kukaid.identify.dynamic.fit_dynamic`);
* ``inertia`` (sine): Izz, Mx (My, offset) by least squares with that friction compensated,
  eqs. (6)-(8);
* ``presliding``: Maxwell-slip elements, eqs. (9)-(10), (12).

Plain ``logs`` are general trajectories: every parameter of the dynamic model is fitted jointly
on them (together with the friction logs when the method is ``joint``).
"""
from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from kukaid import __version__
from kukaid.errors import FitError, OptionError
from kukaid.identify.dynamic import linear_bounded, fit_dynamic
from kukaid.identify.filtering import preprocess, settings_reason
from kukaid.identify.least_squares import fit_rigid
from kukaid.identify.maxwell_slip_fit import fit_maxwell_slip
from kukaid.identify.stribeck_fit import at_bounds, extract_friction, natural_uncertainty, solve_separable
from kukaid.identify.uncertainty import correlation_factor, covariance
from kukaid.jsonfile import jsonable
from kukaid.logs import check_each_recording_once, log_fingerprint
from kukaid.models.friction import MaxwellSlip
from kukaid.models.torque import JointTorqueModel
from kukaid.params.axis import IZZ_MIN, model_sections

METHODS = ("joint", "staged")
FRICTION_MODELS = ("auto", "stribeck", "coulomb-viscous")
#: Stribeck parameters that, on a bound, say the data do not determine the Stribeck rise (delta is a
#: shape exponent within the paper's range 0.5-2; at its limit the rise is still there: the paper's
#: own fit ends at delta = 2.0)
_STRIBECK_EXTRA = ("Fc", "Fs", "Fs-Fc", "vs")


def _model_options(joint: str, gravity: str | None, offset: bool | None) -> tuple[str, bool]:
    """Gravity terms and offset from the joint type when not given.

    A revolute axis: ``Mx cos q``, no offset.  A prismatic axis: gravity along it is a constant force
    (m g sin of the slide's incline) that no fit can tell from an offset, so the default is one
    constant term, the offset, and cos/sin terms of a position in metres are refused."""
    if joint == "prismatic":
        if gravity not in (None, "none"):
            raise FitError(f"--gravity {gravity}: a prismatic axis has no cos/sin gravity terms (its gravity is "
                           "a constant force along the slide, fitted as --offset); use --gravity none")
        return "none", True if offset is None else bool(offset)
    return gravity or "cos", bool(offset)


def _load(x: Any, options: dict) -> Any:
    if hasattr(x, "tau") and hasattr(x, "time"):
        return x
    from kukaid.logs import read_log

    return read_log(x, **options)


def _r(x: float, sig: int = 8) -> float:
    return float(f"{x:.{sig}g}")


def staged_friction(preps: Sequence[Any], friction_model: str = "stribeck",
                    bounds: dict | None = None) -> tuple[dict, dict, float, str, Any]:
    """Friction by the paper's staged method: returns (params, std, mse, status, (points,
    uncertainty, parameters on a bound))."""
    pts = extract_friction(preps)
    v, y = pts.v, pts.gamma_f
    A = np.column_stack([np.ones_like(v), v])
    if friction_model == "stribeck":
        sr = solve_separable(y, A, v, ["Fc", "Fv"], bounds=bounds, where="staged friction")
        params, u = natural_uncertainty(sr)
        res, status = sr.residual, sr.status
        on_bound = sr.at_bound(u.std)
    else:  # within the bounds (--bound), as the joint method's linear fit
        theta, status, info = linear_bounded(y, A, ["Fc", "Fv"], bounds, v)
        res = y - A @ theta
        u = covariance(res, A, ["Fc", "Fv"], theta)
        params = {"Fc": float(theta[0]), "Fv": float(theta[1])}
        on_bound = at_bounds(["Fc", "Fv"], theta, [info["bounds"][k] for k in ("Fc", "Fv")], u.std)
    return params, u.std, float(np.mean(res ** 2)), status, (pts, u, on_bound)


def _adequacy(ax: int, raw_logs: Sequence[Any], preps: Sequence[Any], fit_joint: Any, staged_at_bound: list,
              model: JointTorqueModel, bounds: dict | None) -> dict[str, Any]:
    """Parameters on bounds (``given``: a bound of ``bounds``, the user's), solver status and single-axis
    adequacy (:func:`kukaid.identify.adequacy.assess`)."""
    from kukaid.identify.adequacy import assess, moving_axes, noise_floor, smooth_at_source
    user = {"Fs-Fc" if k == "dF" else k: v for k, v in (bounds or {}).items()}
    on_bound = [{**b, "given": user.get(b["name"], (None, None))[b["side"] == "upper"] is not None}
                for b in list(staged_at_bound) + (list(fit_joint.at_bound_) if fit_joint is not None else [])]
    converged = fit_joint.converged if fit_joint is not None else True
    status = fit_joint.ipopt_status if fit_joint is not None else ""
    rb, friction = model.rigid, model.friction
    res = np.concatenate([(pr.tau - rb.torque(pr.q, pr.qdd) - friction(pr.qd))[pr.dynamic] for pr in preps])
    rms = float(np.sqrt(np.mean(res ** 2))) if res.size else 0.0
    others = sorted({a for lg in raw_logs for a in moving_axes(lg, ax)})
    smooth = all(smooth_at_source(lg.channel("tau", ax)) for lg in raw_logs)  # no white noise to read it from
    warnings, figures = assess(ax, rms, math.nan if smooth else noise_floor(preps), others, on_bound, converged,
                               status)
    return {"at_bound": on_bound, "converged": converged, "warnings": warnings, **figures}


def _model(fp: dict, rigid: dict, friction_model: str) -> JointTorqueModel:
    """The joint-torque model of the fitted friction ``fp`` and rigid-body ``rigid`` parameters."""
    lin = {k: float(v) for k, v in {**fp, **rigid}.items() if k not in ("vs", "delta")}
    return JointTorqueModel(friction_model, lin, float(fp.get("vs", 0.04)), float(fp.get("delta", 1.0)))


def fit_axis(logs: Sequence[Any] = (), friction: Sequence[Any] = (), inertia: Sequence[Any] = (),
             presliding: Any = None, axis: int | None = None, method: str = "joint",
             friction_model: str = "stribeck", gravity: str | None = None, offset: bool | None = None,
             n_elements: int = 3, bounds: dict | None = None, cutoff: float | None = None,
             order: int | None = None, qd_thr: float | None = None, edge: int | None = None,
             decimate: int = 1, reversal_window: float | None = None, diff: str | None = None,
             read_options: dict | None = None) -> dict:
    """Identify one axis; return the parameter dictionary (schema ``kukaid.params/1``).

    Parameters
    ----------
    logs : general logs (AxisLog or paths) fitted jointly.
    friction, inertia : logs of the paper's friction (sweep) and inertia (sine) experiments.
    presliding : log of the pre-sliding experiment (Maxwell-slip), optional.
    axis : KUKA axis number (default: the logs' only axis; required when a log holds several).
    method : "joint" (default) or "staged" (the paper's eqs. 2-5; needs friction sweeps).
    friction_model : "stribeck", "coulomb-viscous" or "auto": Stribeck when the data determine it,
        else Coulomb-viscous (:func:`fit_axis_auto`).
    gravity : "cos", "cos+sin", "none"; offset : fit a constant torque.  Default from the joint
        type (:func:`_model_options`): revolute "cos" without offset, prismatic an offset only.
    n_elements : Maxwell-slip elements.
    bounds : {name: (lo, hi)} overriding the data-derived bounds.
    cutoff, order, qd_thr, edge, decimate, reversal_window, diff : pre-processing
        (:func:`~kukaid.identify.preprocess`).

    Raises
    ------
    FitError : missing data, bad option, failed solve; nothing is written by this function.
    OptionError : no ``axis`` for a log of several axes; the staged method without friction logs.
    """
    if method not in METHODS:
        raise FitError(f"method must be one of {METHODS}, got '{method}'")
    if friction_model not in FRICTION_MODELS:
        raise FitError(f"friction model must be one of {FRICTION_MODELS}, got '{friction_model}'")
    rigid_bound = sorted(k for k in (bounds or {}) if k in ("Izz", "Mx", "My", "offset"))
    if rigid_bound and inertia and (friction or logs):  # fit_rigid below: least squares without bounds
        raise OptionError(f"--bound {', '.join(rigid_bound)}: with --inertia logs beside friction or general logs, "
                          "Izz, Mx (My, offset) are fitted on the inertia logs by least squares with the friction "
                          "compensated (eqs. 6-8), which takes no bounds; bound them in a fit without --inertia "
                          "(its logs as general logs)")
    if friction_model == "auto":
        kw = dict(logs=logs, friction=friction, inertia=inertia, presliding=presliding, axis=axis, method=method,
                  gravity=gravity, offset=offset, n_elements=n_elements, bounds=bounds, cutoff=cutoff, order=order,
                  qd_thr=qd_thr, edge=edge, decimate=decimate, reversal_window=reversal_window, diff=diff,
                  read_options=read_options)
        return fit_axis_auto(**kw)
    ro = dict(read_options or {})
    pre = dict(axis=axis, cutoff=cutoff, order=order, qd_thr=qd_thr, edge=edge, decimate=decimate,
               reversal_window=reversal_window, diff=diff)
    raw_logs: list[Any] = []
    role_warn: list[str] = []
    run_logs: list[str] = []

    def prep(x: Any, role: str | None = None) -> Any:
        from kukaid.identify.adequacy import check_not_held, pushed_log_warnings, role_warnings, unit_warnings

        lg = _load(x, ro)
        name = str(lg.attrs.get("source_file") or (x if isinstance(x, (str, bytes)) or hasattr(x, "__fspath__")
                                                  else "log"))
        if axis is None and len(lg.axes) > 1:  # never a silent choice among several axes
            names = ", ".join(f"A{a}" for a in lg.axes)
            raise OptionError(f"{name}: holds axes {names}; choose one with --axis "
                              "(or fit them all together with --robot URDF)")
        check_not_held(lg, name)
        pushed = pushed_log_warnings(lg, name)
        role_warn.extend(pushed)
        run_logs.extend([name] if pushed else [])
        if role is not None and not pushed:
            role_warn.extend(role_warnings(lg, role, name))
        raw_logs.append(lg)
        pr = preprocess(lg, **pre)
        if role != "presliding":  # the pre-sliding experiment moves a fraction of a degree
            role_warn.extend(unit_warnings(lg, pr.axis, name))
        return pr

    general = [prep(x) for x in logs]
    fr = [prep(x, "friction") for x in friction]
    ine = [prep(x, "inertia") for x in inertia]
    psl = prep(presliding, "presliding") if presliding is not None else None
    if not (general or fr or ine):
        raise FitError("no logs to fit: give general logs, or --friction and/or --inertia logs")
    fitted = raw_logs[:len(general) + len(fr) + len(ine)]  # the pre-sliding log's rests are fitted apart
    check_each_recording_once(fitted, FitError)  # weighed double: standard deviations too small by sqrt 2
    if len(run_logs) == len(raw_logs):  # with an excitation log beside them: a warning (the push is in the fit)
        from kukaid.identify.adequacy import run_logs_only

        raise run_logs_only(run_logs)
    all_preps = general + fr + ine + ([psl] if psl is not None else [])
    axes = {p.axis for p in all_preps}
    if len(axes) > 1:
        which = ", ".join(f"{p.source}: A{p.axis}" for p in all_preps)
        raise FitError(f"the logs are of different axes ({which}): a fit is of one axis; give the logs of one")
    ax = axes.pop()
    try:
        gravity, offset = _model_options(all_preps[0].joint, gravity, offset)
    except FitError as e:  # the joint type is the log's: name it
        raise FitError(f"{all_preps[0].source}: {e}") from None
    qd_thr_used = all_preps[0].qd_thr
    std: dict[str, float] = {}
    metrics: dict[str, Any] = {}
    max_lag = int(math.ceil(2 * all_preps[0].settings["fs"] / all_preps[0].settings["cutoff"]))
    rigid: dict[str, float] = {}
    if method == "staged" and not fr:
        raise OptionError("the staged method needs --friction logs (paired constant-velocity sweeps)")
    staged_at_bound: list[dict] = []
    if fr and method == "staged":
        fp, fstd, fmse, status, (pts, u, staged_at_bound) = staged_friction(fr, friction_model, bounds)
        std.update(fstd)
        metrics.update(friction_fit_mse=fmse, ipopt_status=status, friction_pairs=pts.pairs,
                       friction_condition_number=u.cond)
        fit_joint = None
        if general:
            fit_joint = fit_dynamic(general, friction_model, gravity, offset, bounds=bounds)
    else:
        joint_set = fr + general if fr else general
        fit_joint = fit_dynamic(joint_set, friction_model, gravity, offset, bounds=bounds) if joint_set else None
        fp = {}
        if fit_joint is not None:
            fp = {k: v for k, v in fit_joint.params_.items() if k in ("Fc", "Fs", "vs", "delta", "Fv")}
            std.update(fit_joint.std_)
            rigid = {k: v for k, v in fit_joint.params_.items() if k in ("Izz", "Mx", "My", "offset")}
            resid = np.concatenate([r[m] for r, m in zip(fit_joint.residual_, fit_joint.fitted_)])
            metrics.update(friction_fit_mse=fit_joint.mse_, torque_prediction_mse=fit_joint.mse_,
                           ipopt_status=fit_joint.ipopt_status, condition_number=fit_joint.uncertainty_.cond,
                           correlation={"names": fit_joint.names_,
                                        "matrix": np.round(fit_joint.uncertainty_.corr, 4).tolist()},
                           residual_correlation_factor=correlation_factor(resid, max_lag),
                           n_dynamic_samples=fit_joint.n_samples)
    if not fp:
        # inertia logs only, joint method: fit everything on them
        fit_joint = fit_dynamic(ine, friction_model, gravity, offset, bounds=bounds)
        fp = {k: v for k, v in fit_joint.params_.items() if k in ("Fc", "Fs", "vs", "delta", "Fv")}
        rigid = {k: v for k, v in fit_joint.params_.items() if k in ("Izz", "Mx", "My", "offset")}
        std.update(fit_joint.std_)
        metrics.update(friction_fit_mse=fit_joint.mse_, torque_prediction_mse=fit_joint.mse_,
                       ipopt_status=fit_joint.ipopt_status, condition_number=fit_joint.uncertainty_.cond)
    if ine and (fr or general):
        rf = fit_rigid(ine, _model(fp, {}, friction_model).friction, gravity, offset)
        rigid = dict(rf.params_)
        for k in ("Izz", "Mx", "My", "offset"):
            std.pop(k, None)
        std.update(rf.std_)
        raw = np.concatenate([(pr.tau_raw - pr.tau + r)[pr.dynamic] for pr, r in zip(ine, rf.residual_)])
        metrics.update(torque_prediction_mse=rf.mse_, torque_prediction_mse_raw=float(np.mean(raw ** 2)),
                       inertia_condition_number=rf.uncertainty_.cond)
    elif method == "staged" and fit_joint is not None:
        rigid = {k: v for k, v in fit_joint.params_.items() if k in ("Izz", "Mx", "My", "offset")}
        std.update({k: fit_joint.std_[k] for k in rigid})
    if "Izz" not in rigid:
        raise FitError("Izz cannot be identified from these logs: add an --inertia log or a general log "
                       "with accelerations")
    if rigid["Izz"] < IZZ_MIN:
        raise FitError(f"fitted Izz = {rigid['Izz']:.4g} is not positive: the data do not excite the inertia")
    model = _model(fp, rigid, friction_model)
    model.qd_thr = qd_thr_used
    metrics.update(_adequacy(ax, raw_logs, [p for p in (general + fr + ine) if p is not None], fit_joint,
                             staged_at_bound, model, bounds))
    metrics["warnings"] = role_warn + list(metrics.get("warnings", []))
    if psl is not None:
        ms = fit_maxwell_slip(psl, n_elements, gravity=model.rigid.gravity)
        model.maxwell_slip, model.zeta0 = MaxwellSlip(ms.k, ms.W), tuple(ms.zeta0)
        metrics.update(maxwell_slip_rms=ms.rms, maxwell_slip_sum_W=sum(ms.W), maxwell_slip_samples=ms.n_samples)
        if ms.unsaturated:
            metrics["warnings"].append(
                f"{psl.source}: Maxwell-slip element{'s' if len(ms.unsaturated) > 1 else ''} "
                f"{', '.join(str(i + 1) for i in ms.unsaturated)} break{'' if len(ms.unsaturated) > 1 else 's'} away "
                f"only at half the pre-sliding experiment's swing ({ms.swing / 2:.3g} rad), the most it shows: the "
                "break-away W is not determined by the data beyond it, nor is the friction the axis holds at rest "
                "(a heavier axis's elements need more travel); a pre-sliding experiment of larger reversals "
                "determines it (kukaid excite presliding --reversals-deg, default 0.03,0.015,0.0075,0.00375)")
    out: dict[str, Any] = {"schema": "kukaid.params/1", "axis": int(ax), **model_sections(model, digits=8)}
    values = {**fp, **rigid}
    out["uncertainty"] = {k: _r(v, 4) for k, v in std.items() if k in values}
    metrics["relative_std"] = {k: _r(std[k] / abs(values[k]), 4) for k in out["uncertainty"] if values[k] != 0}
    metrics["std_note"] = ("standard deviations from residual variance and Jacobian assume white residuals; "
                           "filtered data make them optimistic (see residual_correlation_factor)")
    out["metrics"] = jsonable(metrics)
    given = [k for k, v in pre.items() if k != "axis" and v is not None and not (k == "decimate" and v == 1)]
    out["provenance"] = {
        "kukaid_version": __version__, "method": method, "friction_model": friction_model, "gravity": gravity,
        "offset": bool(offset), "joint": all_preps[0].joint,
        "logs": {"general": [p.source for p in general], "friction": [p.source for p in fr],
                 "inertia": [p.source for p in ine], "presliding": psl.source if psl is not None else None},
        # which recordings these are wherever they are later (validate's in-sample warning)
        "log_fingerprints": [log_fingerprint(lg) for lg in raw_logs],
        "preprocess": jsonable({**all_preps[0].settings,
                                "why": settings_reason(all_preps[0].settings, given) + _rates_note(all_preps)}),
    }
    return out


def _rates_note(preps: Sequence[Any]) -> str:
    """Logs at several sample rates are each filtered by their own settings (the summary's are the first
    log's): each rate's, or "" for one rate."""
    by_rate: dict[float, dict] = {}
    for p in preps:
        by_rate.setdefault(round(p.fs, 2), p.settings)
    if len(by_rate) < 2:
        return ""
    return ("; logs at several sample rates, each filtered by its own settings: "
            + ", ".join(f"at {s['fs']:.4g} Hz {s['cutoff']:.4g} Hz order {s['order']}, {s['edge']} edge samples"
                        for s in by_rate.values()))


def fit_axis_auto(**kw: Any) -> dict:
    """Stribeck when the data determine it, else the Coulomb-viscous model it contains.

    The Stribeck model adds Fs, vs and delta to Coulomb-viscous.  When its fit leaves Fc, Fs-Fc
    or vs on a bound (Fc -> 0 with a wide Stribeck bump standing in for the Coulomb level, Fs = Fc,
    a Stribeck velocity outside the speeds in the data), the rise is not determined by the data
    and the nested Coulomb-viscous model is fitted instead.  delta at a limit of its range keeps
    Stribeck (it is still reported as on a bound).  The choice and its reason are in
    ``metrics.friction_model_choice``."""
    st = fit_axis(friction_model="stribeck", **kw)
    bound = [b["name"] for b in st["metrics"].get("at_bound", [])]
    loose = [n for n in bound if n in _STRIBECK_EXTRA]
    if not loose:
        shape = " (delta at a limit of its range 0.5-2)" if "delta" in bound else ""
        st["metrics"]["friction_model_choice"] = f"stribeck: Fc, Fs-Fc and vs are inside their bounds{shape}"
        return st
    cv = fit_axis(friction_model="coulomb-viscous", **kw)
    given = [b["name"] for b in st["metrics"]["at_bound"] if b["name"] in loose and b["given"]]
    data = [n for n in loose if n not in given]
    cv["metrics"]["friction_model_choice"] = "coulomb-viscous: the Stribeck fit left " + "; ".join(
        ([f"{', '.join(data)} on a bound (not determined by these data)"] if data else [])
        + ([f"{', '.join(given)} on the bound --bound gave"] if given else []))
    return cv


def solver_text(status: str) -> str:
    """What solved the fit and how it ended: "IPOPT: Solve_Succeeded", or "linear least squares
    (bounded)" for a fit linear in its parameters (``metrics.ipopt_status`` "linear ...": no IPOPT ran)."""
    return f"linear least squares{status[len('linear'):]}" if status.startswith("linear") else f"IPOPT: {status}"


def _relative(value: float, std: float) -> str:
    """The standard deviation relative to the estimate, "x.xx %", or "-" when the estimate is not
    distinguishable from 0 (|value| below its standard deviation, or 0): a percentage of ~0 is noise."""
    if not (math.isfinite(value) and math.isfinite(std)) or value == 0 or abs(value) < std:
        return "-"
    return f"{100 * std / abs(value):.2f} %"


#: the friction parameters only the Stribeck model has
_STRIBECK_ONLY = ("Fs", "vs", "delta")


def format_table(params: dict) -> str:
    """A short text table of the parameters with their standard deviations."""
    unc = params.get("uncertainty", {})
    rows = []
    names = {}  # the label of a parameter whose file key says something else
    if (params.get("provenance") or {}).get("joint") == "prismatic":
        names = {"Izz": "M"}  # the slide's mass, kept under the file's key Izz
        units = {"Fc": "N", "Fs": "N", "vs": "m/s", "delta": "-", "Fv": "N·s/m", "Izz": "kg",
                 "Mx": "N", "My": "N", "offset": "N", "k": "N/m", "W": "N", "mse": "N²"}
    else:
        units = {"Fc": "N·m", "Fs": "N·m", "vs": "rad/s", "delta": "-", "Fv": "N·m·s/rad", "Izz": "kg·m²",
                 "Mx": "N·m", "My": "N·m", "offset": "N·m", "k": "N·m/rad", "W": "N·m", "mse": "N²m²"}
    cv = params["friction"].get("model") == "coulomb-viscous"  # an edited file's Stribeck terms are not its model's
    items = [(k, v) for k, v in params["friction"].items() if k != "model" and not (cv and k in _STRIBECK_ONLY)]
    items += list(params["inertial"].items())
    if "offset" in params:
        items.append(("offset", params["offset"]))
    m = params.get("metrics") or {}
    refined = isinstance(m.get("original_fit"), dict)  # diagnose -o: the fit's figures are of the model without its effects
    cf = m.get("residual_correlation_factor")
    # the least-squares standard deviations assume white residuals; the filtered residuals are correlated, so
    # the table gives them times the residual correlation factor, as the robot fit's table does (diagnose's
    # refit gives HAC standard deviations: no factor)
    cf = float(cf) if unc and not refined and isinstance(cf, (int, float)) and math.isfinite(cf) else None
    on_bound = {b["name"]: b for b in m.get("at_bound") or []}
    for k, v in items:
        b = on_bound.get(k)
        v = b["bound"] if b else v  # within the solver's tolerance of its bound: the bound (0, not 5.5e-28)
        s = unc.get(k)
        s = s * cf if s is not None and cf is not None else s
        label = names.get(k, k)
        if b:  # a standard deviation from the curvature is no interval at an active bound: the data want beyond it
            rows.append(f"  {label:<7} {v:>12.5g}  {'(at its ' + b.get('side', '') + ' bound)':<25}{units.get(k, '')}")
        elif s is not None:
            rows.append(f"  {label:<7} {v:>12.5g}  +- {s:<10.3g} {_relative(v, s):>9}  {units.get(k, '')}")
        else:
            rows.append(f"  {label:<7} {v:>12.5g}")
    ms = params.get("maxwell_slip")
    if ms:
        rows.append("  Maxwell-slip k = " + ", ".join(f"{x:.4g}" for x in ms["k"]) + f" {units['k']}")
        rows.append("               W = " + ", ".join(f"{x:.4g}" for x in ms["W"]) + f" {units['W']}")
    fm = m["original_fit"] if refined else m
    extra = []
    for key, label in (("friction_fit_mse", "friction fit MSE"), ("torque_prediction_mse", "torque MSE")):
        if key in fm and fm[key] is not None:
            extra.append(f"{label} {fm[key]:.4g} {units['mse']}")
    if "ipopt_status" in fm:
        extra.append(solver_text(fm["ipopt_status"]))
    tail = []
    unused = [k for k in _STRIBECK_ONLY if cv and k in params["friction"]]
    if unused:
        tail.append(f"  not used: friction {', '.join(unused)} (Stribeck parameters; friction.model is coulomb-viscous)")
    if cf is not None:
        tail.append(f"  +-: least-squares standard deviations x the residual correlation factor {cf:.3g} (the filtered "
                    f"residuals are correlated; the file's uncertainty holds them before the factor)")
    if refined:
        ratio = m.get("residual_over_noise")
        tail.insert(0, f"  diagnose's refit with {', '.join(params.get('effects') or {})}: torque RMSE "
                       f"{m['torque_rmse']:.4g} {units['Fc']} on the logs diagnose was given"
                       + (f" ({ratio:.3g} x the noise floor)" if isinstance(ratio, (int, float)) else "")
                       + f"; +-: {m.get('std_note')}")
    at = " in the original fit" if refined else ""
    if fm.get("at_bound"):
        tail.append(f"  at a bound{at}: " + ", ".join(f"{names.get(b['name'], b['name'])} ({b['side']} {b['bound']:.4g}"
                                                    + (", --bound" if b.get("given") else "") + ")"
                                                    for b in fm["at_bound"]))
    else:
        tail.append(f"  at a bound{at}: none")
    pre = (params.get("provenance") or {}).get("preprocess") or {}
    if pre:
        line = (f"  pre-processing: low-pass {pre.get('cutoff', 0):.4g} Hz (order {pre.get('order')}), "
                f"{pre.get('edge')} edge samples trimmed, decimation {pre.get('decimate', 1)}")
        tail.append(line + (f" ({pre['why']})" if pre.get("why") else ""))
    if m.get("friction_model_choice"):
        tail.append(f"  friction model: {m['friction_model_choice']}")
    tail += [f"  warning: {w}" for w in m.get("warnings", [])]
    fig = ("  original fit, without the effects diagnose added: " if refined else "  ") + "; ".join(extra)
    return "\n".join([f"axis A{params['axis']}, friction model {params['friction']['model']}", *rows, fig, *tail])


def format_params(params: dict) -> str:
    """The text table of a one-axis parameter file: :func:`format_table`, with the effects diagnose
    added (a robot's: :func:`kukaid.identify.robot_fit.format_robot_table`; either by
    :meth:`kukaid.identify.fitted.FittedModel.table`)."""
    text = format_table(params)
    eff = params.get("effects") or {}
    prismatic = (params.get("provenance") or {}).get("joint") == "prismatic"
    if eff:
        text += "\n  effects added by diagnose: " + "; ".join(
            f"{name} " + _effect_terms(name, p if isinstance(p, dict) else {}, prismatic) for name, p in eff.items())
    return text


def _effect_terms(name: str, p: dict, prismatic: bool = False) -> str:
    """An effect's terms as the table shows parameters, ``a 0.9422 +- 0.112 N·m``: its ``std`` beside each
    value, not a dictionary of its own, and its unit; the file's tag (``model``) and the thermal drift's
    ``unit`` text (beside ``c`` instead) left out."""
    from kukaid.models.effects import unit_of

    std = p.get("std") if isinstance(p.get("std"), dict) else {}
    out = []
    for k, v in p.items():
        if k in ("model", "std") or (name == "thermal_drift" and k == "unit"):
            continue
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            s = std.get(k)
            u = unit_of(name, k, p, prismatic)
            out.append(f"{k} {v:.4g}" + (f" +- {s:.3g}" if isinstance(s, (int, float)) and math.isfinite(s) else "")
                       + (f" {u}" if u and u != "-" else ""))
        else:
            out.append(f"{k} {v}")
    return ", ".join(out)
