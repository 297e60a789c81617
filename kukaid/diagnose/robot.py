"""Diagnose a robot parameter file (``kukaid.robot_params/1``): which effect a URDF cannot say do
the logs show, on which joints, and does adding it predict recordings its fit did not see better.

The baseline every candidate is judged against, refitted on the training folds (each log left out
in turn, else :data:`FOLDS` contiguous blocks) and judged on the held-out fold, every sample of it:

- each joint's own terms as the file has them (friction, offset; its spring ``k q`` and ripple
  harmonics as changes from the file's values under the file's uncertainty), with the Coulomb
  column as the filtered torque shows it (:func:`kukaid.identify.robot_fit.filtered_coulomb`: the
  step smeared by the fit's low-pass, its transition from :data:`COULOMB_GRID`), the viscous term
  held as the file holds it or linear, and a rotor inertia per joint on top of the file's (chosen per joint by held-out
  error);
- a correction of the file's rigid body (:class:`BaseCorrection`: every base parameter, under a
  prior of the file's uncertainty times its residual correlation factor, scaled by
  :data:`PRIOR_SCALES` as held-out error chooses; the last link's mass and first moments always at
  the file's uncertainty, so a payload stays a candidate of its own).

On the six-axis virtual KR C4 the file as it is (its rigid body fixed, its Coulomb column the sign
of the filtered velocity) predicted clean held-out recordings at 13-23x the noise floor; with
this baseline at 1.2-2.7x (``docs/robot.md``).

Candidates (:mod:`kukaid.diagnose.robot_candidates`): ``counterbalance@A<j>`` (a gas spring, on
the joints that carry at least half of the largest gravity torque range), ``payload`` (the last
link's mass and first moments), per joint ``load_dependent_friction@A<j>``,
``thermal_friction@A<j>`` (with a temperature channel) and ``position_ripple@A<j>``, on a six-axis
robot ``coupled_wrist_friction`` (the wrist motors' friction on their coupled velocities, its
coefficients shared by A4-A6: its ratios chosen on their equations stacked, :class:`_Stacked`), and
``gear_elasticity@A<j>`` on the main axes (the rigid body at the link's lagging state, per unit
compliance).

A candidate's nonlinear settings (the ripple order, the load or the thermal form, a friction
term's own Coulomb transition, the gas spring's geometry: a grid, then a finer one about its pick,
then the ripple's order and the spring's geometry moved continuously: :func:`_pick`) are chosen on
the training folds only, by least squares of the joint's equation with the candidate under the
prior it is judged under (:func:`_prior_rows`: what the prior holds stays held; chosen beside a
rigid body refitted freely, the wrist's ratios took up what the file's wrist links had taken in,
0.09 off on one fold of dev seed 0), so the held-out fold judges the choice too. A ripple's columns are taken from the raw positions through
the fit's low-pass, as the torque is (near the cut-off the filter attenuates a ripple in the
torque, not in a sine of the filtered position). Its coefficients and the baseline are then
fitted on the training folds and the held-out error measured. A counterbalance takes the place of
its joint's spring and ripple terms; it, a payload and the wrist's coupled friction are judged at
every prior strength (a rigid body refitted freely takes part of either in; the baseline's strength
was chosen on a torque the effect dominated), the strength that predicts best among those that make
no joint worse (:func:`_try`), a counterbalance with the gravity parameters of the
links its joint carries free of the file's prior (:meth:`BaseCorrection.freed`: a fit on a
recording with the spring took it in there) and against the same freedom without the spring.
A ripple is tried in the place of its joint's spring and ripple terms (a fit took part of it
there) and beside them, the better by held-out error; either way it must also predict better than
the joint without them (its null tried both ways too: the same freedom). The wrist's coupled
friction takes the place of A5 and A6's own Coulomb and viscous terms and of A4-A6's angle terms,
and is judged with the wrist links' inertial parameters free of the file's prior, the last link's
first moments among them (:meth:`BaseCorrection.freed_inertia`; a fit took part of it there; its
ratios chosen with those first moments held), against the same without the coupling.
Load-dependent and thermal friction are judged with the gravity parameters of the links their joint
carries free of the file's prior (a fit took part of either there: a friction torque
that switches with the joint's direction is its gravity torque wherever it moves against gravity),
against the same freedom without them (thermal friction: its friction terms without the
temperature). Recordings the file was fitted on are not used when
at least two others remain (:func:`_unseen`).

A candidate is named when it lowers the held-out relative error of the joints it acts on by more
than :data:`MARGIN` (below the baseline's and below what the candidate without what names it
predicts, where it says: a thermal friction's friction terms without the temperature), makes no
joint's held-out error worse by as much (and by more than :data:`WORSE_FLOOR` of its noise floor),
its gain is at least :data:`MIN_T` standard errors of its spread over blocks of the held-out
recordings (the log of the squared-error ratio per block), and its refit
on all samples passes its plausibility rule; the best is added (the joints' own choices and the
prior's strength made again with it beside: made without it, they were made on a torque it
dominated) and the others tried again (at most ``max_steps``). Another candidate of that round on
the same joints whose held-out gain is not :data:`MIN_T` standard errors from the best's, when
neither lowers the held-out error given the other, explains the same residual: it is named beside
the best as an undetermined mechanism (the step's ``undetermined``: both, and the measurement that
would settle it, :func:`kukaid.diagnose.ambiguity.settled_by`) and not added. The noise floor per joint
(:func:`kukaid.diagnose.noise.filtered_noise_floor`: the RMSE of a perfect model in the fit's
filtered comparison) is reported beside the errors.

The result carries the refined file (``params``, :func:`_refined`: the named effects in
``effects``, the file's own terms refitted beside them, as ``kukaid diagnose -o`` writes it) and the
held-out residuals at the start and after each step (``series``, :mod:`kukaid.diagnose.robot_plots`
draws them). A file's own effects are held in the baseline and not tried again.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from kukaid.diagnose.robot_candidates import Context, RobotCandidate, robot_candidates
from kukaid.errors import KukaidError
from kukaid.identify.adequacy import smooth_at_source
from kukaid.params.robot import check_fitted_urdf

#: a candidate must lower the held-out relative error of the joints it acts on by this share
MARGIN = 0.05
#: a joint counts as made worse by a candidate only when its held-out RMSE grows by more than this
#: share of its noise floor (and by :data:`MARGIN`)
WORSE_FLOOR = 0.25
#: contiguous blocks of one recording when there is only one (and of each held-out recording, for the
#: spread of a candidate's held-out gain)
FOLDS = 5
#: a candidate's held-out gain must be at least this many standard errors of its spread over the
#: held-out blocks (about a 5 % one-sided chance that a candidate with no gain passes)
MIN_T = 2.0


@dataclass
class Series:
    """What a report draws: over the diagnosis' samples (N,), the time s (each recording's own),
    samples per recording, the file's signals (positions, temperatures, load torques:
    :class:`~kukaid.models.robot_effects.EffectSignals`) and the held-out residual (measured minus
    predicted, filtered as compared; (N, n) N·m) at the start and after each named effect."""

    time: np.ndarray
    log_rows: tuple[int, ...]
    signals: Any
    residuals: list


#: the file's terms refitted held out below this share of the file's own error: the file is said to be worth refitting
REFIT_BETTER = 0.7


@dataclass
class RobotDiagnosis:
    """Result of :func:`diagnose_robot`: ``lines()`` for the terminal, ``to_json()`` for a machine,
    ``params`` the refined parameter file (the named effects in it), ``series`` for a report."""

    axes: list[int]
    folds: str
    before: list[float]                    # held-out relative error per joint, the file's terms refitted
    after: list[float]
    steps: list[dict] = field(default_factory=list)
    rejected: list[dict] = field(default_factory=list)
    in_sample: list[float] = field(default_factory=list)   # the file as it is, relative error per joint
    noise_floor: list[float] = field(default_factory=list)  # N·m per joint: the RMSE of a perfect model
    smooth: list[bool] = field(default_factory=list)        # per joint: torque smoothed at the source, floor unknown
    rms: list[float] = field(default_factory=list)          # N·m per joint: RMS of the compared torque
    tried: list[dict] = field(default_factory=list)         # every candidate of the first round, its evidence
    fitted_on: list[str] = field(default_factory=list)      # recordings the file was fitted on: not used
    given: list[str] = field(default_factory=list)          # the file's own effects: held, not candidates
    params: dict | None = None                              # the refined parameter file
    series: Series | None = field(default=None, repr=False)
    tested: bool = True                                     # candidates were tested (not --max-steps 0)
    unit_doubt: bool = False                                # a log's positions looked like radians under degrees

    @property
    def names(self) -> list[str]:
        return [s["name"] for s in self.steps]

    @property
    def floor_unknown(self) -> list[bool]:
        """Per joint: its noise floor is not known (its torque was smoothed at the source)."""
        return self.smooth or [False] * len(self.noise_floor)

    def rmse(self, rel: Sequence[float]) -> np.ndarray:
        """Relative errors per joint -> RMSE per joint, N·m."""
        return np.asarray(rel, float) * np.asarray(self.rms, float)

    def joints(self) -> list[dict[str, Any]]:
        """Per joint, as :meth:`kukaid.diagnose.result.Diagnosis.joints`: held out, after the effects."""
        rmse = self.rmse(self.after) if self.rms else [None] * len(self.axes)
        return [{"axis": int(a), "rmse": None if e is None else float(e), "rel_error": float(self.after[k]),
                 "effects": [s["name"] for s in self.steps if f"A{a}" in s["joints"]]}
                for k, (a, e) in enumerate(zip(self.axes, rmse))]

    def to_json(self) -> dict[str, Any]:
        return {"schema": "kukaid.robot_diagnosis/1", "axes": self.axes, "folds": self.folds,
                "relative_error_given": self.in_sample, "heldout_relative_error_before": self.before,
                "heldout_relative_error_after": self.after,
                "noise_floor_Nm": [None if k else f for f, k in zip(self.noise_floor, self.floor_unknown)],
                "heldout_rmse_before_Nm": self.rmse(self.before).tolist() if self.rms else [],
                "heldout_rmse_after_Nm": self.rmse(self.after).tolist() if self.rms else [],
                "steps": self.steps, "rejected": self.rejected, "tried": self.tried,
                "not_used_fitted_on": self.fitted_on, "effects_in_the_file": self.given}

    def lines(self) -> list[str]:
        ax = " ".join(f"{f'A{a}':>7}" for a in self.axes)
        out = [f"robot diagnosis, held out: {self.folds}"]
        if self.fitted_on:
            out.append(f"  not used: {', '.join(self.fitted_on)} (the file was fitted on it: its error is in-sample)")
        if self.given:
            out.append(f"  in the file already (held, not tried again): {', '.join(self.given)}")
        out += [f"{'relative error':<34}{ax}",
                f"{'  the file as it is':<34}" + " ".join(f"{100 * x:6.1f}%" for x in self.in_sample),
                f"{'  held out, its terms refitted':<34}" + " ".join(f"{100 * x:6.1f}%" for x in self.before)]
        for k, st in enumerate(self.steps, 1):
            label = "  + " + st["name"]
            out.append(f"{label:<34}" + " ".join(f"{100 * x:6.1f}%" for x in st["heldout_after"]))
        if self.noise_floor and self.rms:
            fl = 100 * np.asarray(self.noise_floor) / np.maximum(np.asarray(self.rms), 1e-300)
            out.append(f"{'  noise floor (a perfect model)':<34}" + " ".join(
                f"{'n/a':>7}" if k else f"{x:6.1f}%" if x >= 0.05 or x == 0 else f"{'<0.1':>6}%"
                for x, k in zip(fl, self.floor_unknown)))
            smooth = [f"A{a}" for a, k in zip(self.axes, self.floor_unknown) if k]
            if smooth:
                out.append(f"  noise floor n/a on {', '.join(smooth)}: the torques are smooth sample to sample (filtered "
                           "before they were recorded), so their noise cannot be told from them")
        b, f = float(np.mean(self.before)) if self.before else 0.0, float(np.mean(self.in_sample)) if self.in_sample else 0.0
        if b < REFIT_BETTER * f:  # a stale or under-determined file: the user's remedy is a refit, not an effect
            if self.unit_doubt:  # a refit on logs in the wrong unit fits the mistake
                remedy = ("mend the logs' position unit first (the warnings above): a refit on them as they are "
                          "would fit that mistake")
            else:
                remedy = ("`kukaid fit --robot` on these logs gives that model (the diagnosis names missing effects; it "
                          "keeps the file's terms)")
            out.append(f"  the file's own terms refitted on these logs predict them held out at {100 * b:.1f} % against "
                       f"{100 * f:.1f} % for the file as it is: {remedy}")
        if self.steps:
            for k, st in enumerate(self.steps, 1):
                par = ", ".join(f"{k2} {v:.4g}" if isinstance(v, float) else f"{k2} {v}" for k2, v in st["params"].items())
                out.append(f"step {k}: {st['name']} ({par}): held-out error of {', '.join(st['joints'])} "
                           f"{100 * st['mean_before']:.1f} -> {100 * st['mean_after']:.1f} %")
                u = st.get("undetermined")
                if u:
                    alone = ", ".join(f"{nm} {100 * x:.2f} %" for nm, x in u["heldout_relative_error"].items())
                    out.append(f"    mechanism undetermined: {' or '.join(u['candidates'])} explain the same residual "
                               f"(held out, each alone: {alone}; neither adds to the other); modelled as "
                               f"{u['modelled_as']}, the larger held-out gain; to settle it: {u['settled_by']}")
        elif not self.tested:  # as the one-axis diagnosis says it
            out.append("no candidate tested (--max-steps 0): the figures above are all this run measured")
        else:
            out.append("no effect named: none lowers the held-out error enough")
        for r in self.rejected:
            out.append(f"not named: {r['name']}: {r['reason']}")
        return out


#: transition velocities of the diagnosis' Coulomb column ``tanh(qd / v)`` (rad/s), chosen per joint by
#: held-out error; the velocity is the positions' through a low-pass :data:`VELOCITY_BAND` times the
#: fit's cut-off, so a stop shows as it happens (the column then goes through the fit's low-pass)
COULOMB_GRID = (0.001, 0.003, 0.01, 0.03)
VELOCITY_BAND = 4.0
#: a candidate's nonlinear settings are chosen with the prior it is judged under (:func:`_prior_rows`)
PICK_WITH_PRIOR = True
#: values (raw samples x columns) a candidate's columns are filtered in at once (memory: 8 bytes each)
LOWPASS_VALUES = 2 ** 21
#: values a diagnosis keeps of a candidate's finer options' columns (:class:`_Batches`), and a
#: quarter of it of its filtered motor columns (:class:`_ColumnCache`); 8 bytes each
CACHED_VALUES = 2 ** 21
#: multiples of the prior's information (the file's uncertainty) tried for the rigid body's correction
#: (1e6: the file's rigid body as it is)
PRIOR_SCALES = (1e6, 1.0, 1e-2, 1e-4)


class _ColumnCache:
    """Columns by key, the least recently used dropped beyond ``limit`` values (default
    :data:`CACHED_VALUES`)."""

    def __init__(self, limit: int | None = None) -> None:
        from collections import OrderedDict

        self._d: OrderedDict = OrderedDict()
        self._size, self._limit = 0, CACHED_VALUES if limit is None else limit

    def get(self, key):
        col = self._d.get(key)
        if col is not None:
            self._d.move_to_end(key)
        return col

    def put(self, key, col: np.ndarray) -> np.ndarray:
        self._d[key] = col
        self._size += col.size
        while self._size > self._limit and len(self._d) > 1:
            self._size -= self._d.popitem(last=False)[1].size
        return col


class _Batches:
    """A candidate's columns of a list of options (:meth:`RobotCandidate.batch`), kept while it is
    judged: its grid (the last one asked for) and its finer options' (the least recently used
    dropped beyond :data:`CACHED_VALUES` values). A candidate judged at every prior strength, in the
    place of its joint's angle terms and beside them, asks for the same grid each time (a
    counterbalance's 720 gas-spring shapes, a ripple's orders through the fit's low-pass)."""

    def __init__(self) -> None:
        self._grid: tuple | None = None
        self._fine = _ColumnCache()

    @staticmethod
    def _key(view, options: list) -> tuple:
        stacked = (tuple(view.J), view.sw.tobytes()) if isinstance(view, _Stacked) else None
        return stacked, tuple(tuple(sorted(o.items())) for o in options)

    def batch(self, view, ctx: Context, options: list, grid: bool = False) -> np.ndarray:
        key = self._key(view, options)
        if grid:
            if self._grid is None or self._grid[0] != key:
                self._grid = (key, view.batch(ctx, options))
            return self._grid[1]
        B = self._fine.get(key)
        return B if B is not None else self._fine.put(key, view.batch(ctx, options))


@dataclass
class _Baseline:
    """The joints' own columns the diagnosis refits beside a candidate, with its choices: per joint
    the Coulomb transition (index into :data:`COULOMB_GRID`, or the last: the file's own column), the
    viscous form ("hold" as the file, or "linear") and a rotor inertia or not. ``coulomb`` (N, n,
    V + 1), ``viscous`` {form: (N, n)}; ``cols(j, v, form, rotor)``."""

    base: list                 # per joint (N, c): the file's own columns (Coulomb and viscous replaced)
    ic: list                   # per joint: the Coulomb column's index in base[j]
    iv: list                   # per joint: the viscous column's index
    coulomb: np.ndarray
    viscous: dict
    qdd: np.ndarray
    prior: list = field(default_factory=list)   # per joint: information of a prior at 0 per column of cols()
    angle: list = field(default_factory=list)   # per joint: indices of its terms of its own angle (k, ripple)
    angle_torque: np.ndarray | None = None      # (N, n) those terms' torque as the file has them
    names: list = field(default_factory=list)   # per joint: the file's names of its own columns (A2.Fc, ...)

    def without_angle_terms(self, j: int, r: np.ndarray, Fj: list) -> tuple[np.ndarray, list]:
        """``r`` and ``Fj`` with joint j's terms of its own angle taken out (the file's torque of them
        given back to ``r``, their columns zero): a counterbalance candidate takes their place (the
        fit's spring and ripple terms are what stood in for one on the recording it was fitted on), as
        a position ripple does. Taken out already (their columns zero): as they are."""
        if not self.angle or not self.angle[j] or not np.any(Fj[j][:, self.angle[j]]):
            return r, Fj
        r = r.copy()
        r[:, j] += self.angle_torque[:, j]
        F = Fj[j].copy()
        F[:, self.angle[j]] = 0.0
        return r, [F if i == j else f for i, f in enumerate(Fj)]

    def without_friction(self, j: int, Fj: list) -> list:
        """``Fj`` with joint j's Coulomb and viscous columns zero (a candidate's friction takes their place)."""
        F = Fj[j].copy()
        F[:, [self.ic[j], self.iv[j]]] = 0.0
        return [F if i == j else f for i, f in enumerate(Fj)]

    def cols(self, j: int, v: int, form: str, rotor: bool = True) -> np.ndarray:
        F = self.base[j].copy()
        F[:, self.ic[j]] = self.coulomb[:, j, v]
        F[:, self.iv[j]] = self.viscous[form][:, j]
        # + the joint's rotor inertia (a zero column when left out: the prior's indices stay)
        return np.concatenate([F, self.qdd[:, j:j + 1] if rotor else np.zeros((F.shape[0], 1))], axis=1)


def _signals(params: dict, logs: Sequence[Any], robot):
    """The fit's samples of the logs (filtered, trimmed, decimated), the file's rigid-body torque,
    each joint's own columns (:class:`_Baseline`), the file's prediction, the candidates' pieces
    (gravity, payload columns, times, temperatures), the rigid body's correction columns and the
    noise floor."""
    from kukaid.identify.robot_fit import (DriveModel, RobotFitSettings, _blocks, _cutoff, _samples, effect_signals,
                                           ZeroPhaseLowPass, extra_names, extras, filtered_coulomb, fit_lowpass,
                                           log_temperatures, rigid_at, sample_rows, wide_velocity)
    from kukaid.models import robot_effects

    s = params["settings"]
    settings = RobotFitSettings(**{"ripple": 0, **{k: s[k] for k in RobotFitSettings.__dataclass_fields__ if k in s}})
    if settings.torque_side != "joint":
        raise KukaidError("diagnose: robot parameter files with motor-side torques are not supported yet (fit with "
                          "joint-side torques)")
    n = robot.n
    dr = params.get("drive") or {}
    drive = DriveModel(np.asarray(dr["ratio"], float), np.asarray(dr["coupling"], float), np.zeros(n)) \
        if settings.rotor else DriveModel.direct(n)
    m = _samples(logs, n, settings, drive)
    names = extra_names(robot, settings)
    fr = params["friction"]
    x = np.array([fr["values"].get(k, 0.0) for k in names])
    rotors = [i for i, k in enumerate(names) if k.endswith(".rotor_inertia")]
    N = m.q.shape[0]
    times, temps = [], []
    for lg in logs:
        rows = sample_rows(lg, settings)
        times.append(np.asarray(lg.time, float)[rows])
        temps.append(None if getattr(lg, "temp", None) is None else log_temperatures(lg, n)[rows])
    temp = None if any(t is None for t in temps) else np.concatenate(temps)
    time_all = np.concatenate(times)
    rigid, gravity, sign, friction, fixed = (np.empty((N, n)) for _ in range(5))
    effects = params.get("effects") or {}
    # each joint's own terms as the file has them: ripple harmonics the fit held at 0 (not covered by
    # its range, or not chosen) stay out, else their refit bends the torque outside the fitted range
    own = [[i for i, nm in enumerate(names) if nm.startswith(f"A{j + 1}.") and not (".ripple_" in nm and x[i] == 0.0)]
           for j in range(n)]
    coul = [names.index(f"A{j + 1}.Fc") for j in range(n)]
    visc = [names.index(f"A{j + 1}.Fv") for j in range(n)]
    Fj = [np.empty((N, len(c))) for c in own]
    hold = np.empty((N, n))
    payload = np.empty((N, n, 4))
    B = BaseCorrection(robot, params)
    corr = np.empty((N, n, B.size))
    fit_file = np.empty((N, n))
    for rows, mb in _blocks(m):
        Y = robot.regressor(mb.q, mb.qd, mb.qdd)
        F = extras(robot, mb, settings, drive, qd_range=fr.get("qd_range"))
        es = effect_signals(robot, mb.q, Y, F, params, names, None if temp is None else temp[rows], qd=mb.qd,
                            qdd=mb.qdd, time=time_all[rows])
        rigid[rows], gravity[rows], payload[rows], sign[rows], friction[rows] = (
            es.rigid, es.gravity, es.payload, es.sign, es.friction)
        # the file's own effects and rotor inertias: held as it has them
        fixed[rows] = robot_effects.torque(effects, es) + F[:, :, rotors] @ x[rotors]
        corr[rows] = B.columns(Y)
        hold[rows] = F[:, np.arange(n), visc]
        for j in range(n):
            Fj[j][rows] = F[:, j, own[j]]
            fit_file[rows, j] = F[:, j, own[j]] @ x[own[j]]
    tau_hat = rigid + fit_file + fixed
    # the file's terms of a joint's own angle (spring k q_j, ripple harmonics) are refitted as changes
    # from the file's values under its uncertainty: refitted freely on a recording that covers a
    # narrow range of the joint they extrapolate (a file's k of 92 N·m/rad on A2: 150 % held out)
    cf = float((params.get("metrics") or {}).get("residual_correlation_factor") or 1.0)
    sd = fr.get("sigma") or {}
    shape = np.zeros((N, n))
    own_prior = []
    for j in range(n):
        pj = np.zeros(len(own[j]) + 1)
        for i, k in enumerate(own[j]):
            if names[k].endswith(".k") or ".ripple_" in names[k]:
                shape[:, j] += Fj[j][:, i] * x[k]
                v = cf * float(sd.get(names[k], math.nan) or math.nan)
                pj[i] = 1.0 / v ** 2 if math.isfinite(v) and v > 0 else 1e12
        own_prior.append(pj)
    # the Coulomb step as the filtered torque shows it (smeared over a cut-off period at a reversal,
    # a stop's creep at its low-speed friction), not the step of the filtered velocity's sign
    coulomb = np.concatenate([filtered_coulomb(lg, n, settings, sample_rows(lg, settings), v_smooth=COULOMB_GRID,
                                               velocity_cutoff=VELOCITY_BAND * _cutoff(settings, 1.0 / lg.sample_time))
                              for lg in logs])
    # the file's own column (the sign of the filtered velocity) the last option
    coulomb = np.concatenate([coulomb, np.column_stack([Fj[j][:, own[j].index(coul[j])] for j in range(n)])[:, :, None]],
                             axis=2)
    base = _Baseline(Fj, [own[j].index(coul[j]) for j in range(n)], [own[j].index(visc[j]) for j in range(n)],
                     coulomb, {"hold": hold, "linear": m.qd}, m.qdd, own_prior,
                     [[i for i, k in enumerate(own[j]) if names[k].endswith(".k") or ".ripple_" in names[k]]
                      for j in range(n)], shape, [[names[k] for k in own[j]] for j in range(n)])
    fs = [1.0 / lg.sample_time for lg in logs]

    # each log's fit low-pass and rows, made once: the candidates' columns are filtered thousands of times
    filt = [ZeroPhaseLowPass(fit_lowpass(lg, settings)) for lg in logs]
    at_rows = [sample_rows(lg, settings) for lg in logs]
    # logs of one length and one filter are filtered together, columns side by side (each column
    # alone: the same result to the bit); a call costs about what its checks do on a 10 s log
    groups: dict = {}
    for k, (lg, f) in enumerate(zip(logs, filt)):
        groups.setdefault((lg.n_samples, f.sos.tobytes()), []).append(k)
    groups = list(groups.values())

    def filtered(cols: dict) -> dict:
        """{log index: (M, c) values} -> {log index: (rows, c) through its fit low-pass}."""
        out = {}
        for g in groups:
            ks = [k for k in g if k in cols]
            if not ks:
                continue
            Y = filt[ks[0]](np.concatenate([cols[k] for k in ks], axis=1) if len(ks) > 1 else cols[ks[0]])
            at = 0
            for k in ks:
                c = cols[k].shape[1]
                out[k] = Y[:, at:at + c][at_rows[k]]
                at += c
        return out

    def lowpass(j, fn, width):
        qs = [np.asarray(lg.q[:, lg.index(j + 1)], float) for lg in logs]
        if sum(lg.n_samples for lg in logs) * width <= LOWPASS_VALUES:     # every log's columns at once
            got = filtered({k: fn(q, 0, width) for k, q in enumerate(qs)})
            return np.concatenate([got[k] for k in range(len(logs))])
        out = []
        for lg, f, rows, q in zip(logs, filt, at_rows, qs):
            step = max(1, int(LOWPASS_VALUES // lg.n_samples))    # columns filtered at once
            out.append(np.concatenate([f(fn(q, a, min(a + step, width)))[rows] for a in range(0, width, step)], axis=1))
        return np.concatenate(out)

    wide = {}
    motor = _ColumnCache(CACHED_VALUES // 4)

    def motor_coulomb(mix, v):
        """(N, k) each motor's Coulomb column (a row of ``mix``) through the fit's low-pass: a motor's
        column depends on its own row and ``v`` alone, and the wrist's ratio grids share rows (125
        options: 5 rows of motor 5, 25 of motor 6), so each is filtered once (:class:`_ColumnCache`)."""
        keys = {(k, i): (k, i, mix[i].tobytes(), float(v)) for k in range(len(logs)) for i in range(mix.shape[0])}
        have = {ki: motor.get(key) for ki, key in keys.items()}
        todo: dict = {}
        for k, lg in enumerate(logs):
            miss = [i for i in range(mix.shape[0]) if have[k, i] is None]
            if miss:
                if k not in wide:     # every joint's velocity from the wider band, once per log
                    wide[k] = wide_velocity(lg, n, settings, VELOCITY_BAND * _cutoff(settings, 1.0 / lg.sample_time))
                todo[k] = (miss, np.tanh(wide[k] @ mix.T / v)[:, miss])
        got = filtered({k: a for k, (_, a) in todo.items()})
        for k, (miss, _) in todo.items():
            for c, i in enumerate(miss):
                have[k, i] = motor.put(keys[k, i], np.ascontiguousarray(got[k][:, c:c + 1]))
        return np.concatenate([np.concatenate([have[k, i] for i in range(mix.shape[0])], axis=1)
                               for k in range(len(logs))])

    pieces = dict(q=m.q, lowpass=lowpass, motor_coulomb=motor_coulomb, qd=m.qd, tau=m.tau, gravity=gravity, rigid=rigid, temp=temp, payload=payload,
                  total_mass=float(np.sum(np.maximum(robot.pi_nominal[0::10], 0))), log_rows=m.log_rows or (N,),
                  cutoff=_cutoff(settings, min(fs)), time=time_all, at_rest=sign == 0.0,
                  Fc=np.array([x[c] for c in coul]), Fv=np.array([x[c] for c in visc]))
    # what the file's effects read, its own Coulomb column and friction: a refined file's effects are
    # refitted on it (:func:`_refined`)
    bp = params["base_parameters"]
    at_state = rigid_at(robot, m.q, m.qd, m.qdd, np.asarray(bp["independent"], int), np.asarray(bp["values"], float))
    pieces["rigid_at"] = at_state
    own_signals = robot_effects.EffectSignals(q=m.q, sign=sign, friction=friction, gravity=gravity, rigid=rigid,
                                              payload=payload, temp=temp, qd=m.qd, time=time_all, rigid_at=at_state,
                                              log_rows=tuple(m.log_rows or (N,)))
    from kukaid.diagnose.noise import filtered_noise_floor

    floor = [filtered_noise_floor([lg.tau[:, lg.index(j + 1)] for lg in logs], fs, [_cutoff(settings, f) for f in fs],
                                  settings.order) for j in range(n)]
    return (m, rigid + shape + fixed, base, tau_hat, pieces, [corr[:, j, :] for j in range(n)], B,
            np.asarray(floor), own_signals)


class BaseCorrection:
    """Columns of a correction to the file's rigid body (every base parameter) and its prior: the
    file's estimate with its standard deviations times its residual correlation factor (the fit's
    honest uncertainty), so the diagnosis judges candidates with the rigid body refitted on the
    training folds where the file is uncertain (a file fitted on one short recording predicts others
    at several times the noise floor from its estimation error alone: on the six-axis virtual KR C4,
    5-12x on the wrist) and held where it is not (a free refit of 36 parameters on one recording
    extrapolates a joint's gravity to angles it did not see). A payload changes the last link far
    beyond the file's uncertainty: the payload candidate's columns are not penalised."""

    def __init__(self, robot, params: dict) -> None:
        bp = params["base_parameters"]
        self.independent = np.asarray(bp["independent"], int)
        sd = np.asarray(bp.get("sigma") or [np.nan] * self.independent.size, float)
        c = float((params.get("metrics") or {}).get("residual_correlation_factor") or 1.0)
        sd = c * sd
        ok = np.isfinite(sd) & (sd > 0)
        # the prior's information matrix (a parameter with no uncertainty stays as the file has it)
        D = np.diag(np.where(ok, 1.0 / np.where(ok, sd, 1.0) ** 2, 1e12))
        # its part in the payload's directions (the last link's mass and first moments in the base):
        # kept at the file's uncertainty whatever the prior's strength, so a payload is a candidate of
        # its own and not a correction of the rigid body
        base = robot.base_parameters()
        self._K = base.K(robot.n_std) if np.array_equal(np.sort(self.independent), base.independent) else None
        Q = self._span(robot.n_std - 10, 4)
        Pq = Q @ Q.T
        #: (information, its payload part): the prior at strength c is c info + (1 - c) payload part
        self.prior = (D, Pq @ D @ Pq)
        self.size = self.independent.size
        self.n = robot.n

    def _span(self, k0: int, k: int) -> np.ndarray:
        """An orthonormal basis (size, r) of the base parameters' directions of the standard
        parameters k0 .. k0 + k - 1 (none when the file's base parameters are not the URDF's)."""
        if self._K is None:
            return np.zeros((self.independent.size, 0))
        U, sv, _ = np.linalg.svd(self._K[:, k0: k0 + k], full_matrices=False)
        return U[:, sv > 1e-9 * max(float(sv.max()), 1e-300)]

    def freed(self, prior: tuple, j: int) -> tuple:
        """``prior`` (information, payload part) without information in the directions of the masses
        and first moments of the links joint j carries (all but the last: a payload's), its gravity
        torque: a fit on a recording with a counterbalance on joint j took the spring's torque there
        (its first harmonic of the joint's angle is a link's first moment), the rest in the joint's
        spring and ripple terms, and the file's uncertainty is of that sum."""
        return self._free(prior, [self._span(10 * k, 4) for k in range(j, self.n - 1)])

    def freed_inertia(self, prior: tuple, links: Sequence[int], moments: bool = True) -> tuple:
        """``prior`` without information in the directions of every inertial parameter of ``links``
        (0-based): a fit on a recording with friction its per-joint terms could not hold (a wrist's
        coupled friction) took part of it into the inertial parameters of the links those joints
        move, the last link's first moments among them (six-axis virtual KR C4, wrist dev seed 2:
        link 6's ``mz`` 9.8 of the file's uncertainties from the truth, link 5's 6.3, link 4's 5.6;
        held as a payload's, A4-A6 ended 5.7x the noise floor after the coupled friction, its twin
        1.5x). ``moments`` False: of the last link its inertia tensor only, its first moments held
        (on the KR 6 R700 its ``my``, ``mz``: its mass and ``mx`` are in base parameters shared with
        links 4 and 5's, free with them either way)."""
        return self._free(prior, [self._span(10 * k + 4, 6) if k == self.n - 1 and not moments
                                  else self._span(10 * k, 10) for k in links])

    def _free(self, prior: tuple, spans: list) -> tuple:
        """``prior`` without information in the directions of the columns of ``spans``."""
        Q = np.concatenate(spans, axis=1) if spans else np.zeros((self.size, 0))
        if Q.shape[1]:
            U, sv, _ = np.linalg.svd(Q, full_matrices=False)
            Q = U[:, sv > 1e-9 * float(sv.max())]
        R = np.eye(self.size) - Q @ Q.T
        return tuple(R @ M @ R for M in prior)

    def columns(self, Y: np.ndarray) -> np.ndarray:
        """(B, n, size) from the standard regressor (B, n, 10 n)."""
        return Y[:, :, self.independent]


def _choose_baseline(base: _Baseline, r, tau, corr, prior, folds, K, w, local: dict | None = None,
                     replaced: Sequence[int] = ()) -> tuple[list, list]:
    """Each joint's Coulomb transition and viscous form by its held-out error (every joint given the
    same option in turn, the rigid body's correction refitted beside; each joint takes its best).
    ``local``, ``replaced``: named effects' columns refitted beside, the joints whose terms of their
    own angle a named effect took the place of. Returns the joints' own columns and the choice per
    joint ``(v index, form, rotor)``."""
    n = r.shape[1]
    opts = [(v, f, rot) for rot in (True, False) for f in ("hold", "linear") for v in range(base.coulomb.shape[2])]

    def cols(choice):
        F = [base.cols(j, *choice[j]) for j in range(n)]
        for j in replaced:
            F = base.without_angle_terms(j, r, F)[1]
        return F

    errs = []
    for o in opts:
        num, _, _, _ = _heldout(r, tau, cols([o] * n), corr, local or {}, folds, K, w, prior=prior)
        errs.append(num.sum(0))
    best = np.argmin(np.array(errs), axis=0)
    choice = [opts[int(b)] for b in best]
    return cols(choice), choice


def _baselines(base: _Baseline, r, tau, shared, prior, folds, K, w, local: dict | None = None,
               replaced: Sequence[int] = ()) -> dict:
    """The joints' own columns chosen (:func:`_choose_baseline`) at each prior strength of
    :data:`PRIOR_SCALES`: {strength: (columns, choice, held-out squared error per fold (K, n), held-out
    residual per sample (N, n))}."""
    out = {}
    for c in PRIOR_SCALES:
        F, choice = _choose_baseline(base, r, tau, shared, _scaled(prior, c), folds, K, w, local, replaced)
        num, _, _, res = _heldout(r, tau, F, shared, local or {}, folds, K, w, prior=_scaled(prior, c))
        out[c] = (F, choice, num, res)
    return out


def _weighted(num: np.ndarray, w: np.ndarray) -> float:
    """Held-out squared error per fold and joint (K, n) summed with the joints' weights."""
    return float(np.sum(num.sum(0) * w))


def _scaled(prior, c):
    info, keep = prior[1]
    return ([p * c for p in prior[0]], c * info + (1.0 - c) * keep)


def _context(pieces: dict, base: _Baseline, choice: list) -> Context:
    """The candidates' view: the chosen Coulomb column as ``sign`` and the file's friction on it."""
    n = len(choice)
    sign = np.column_stack([base.coulomb[:, j, choice[j][0]] for j in range(n)])
    visc = np.column_stack([base.viscous[choice[j][1]][:, j] for j in range(n)])
    p = dict(pieces)
    Fc, Fv = p.pop("Fc"), p.pop("Fv")
    grid = base.coulomb[:, :, :len(COULOMB_GRID)]
    return Context(sign=sign, friction=sign * Fc + visc * Fv, transitions=COULOMB_GRID, coulomb=grid,
                   friction_at=grid * Fc[None, :, None] + (visc * Fv)[:, :, None], **p)


class _SharedRows:
    """Per fold, the shared columns' rows of each joint and their block of the normal equations
    (``sum_j w_j S_j^T S_j``, summed in :func:`_heldout`'s order: the same to the bit), kept for the
    last :attr:`size` (shared columns, fold) pairs: a diagnosis fits the same shared columns (the
    rigid body's correction) beside every candidate on one joint, hundreds of times. Keyed by the
    arrays themselves (held by weak references: nothing is kept alive) and the weights."""

    size = 8

    def __init__(self) -> None:
        import threading
        from collections import OrderedDict

        self._d: OrderedDict = OrderedDict()
        self._lock = threading.Lock()

    def get(self, shared: list, folds: np.ndarray, f: int, w: np.ndarray, rows: np.ndarray):
        import weakref

        key = (tuple(id(S) for S in shared), id(folds), int(f), np.asarray(w, float).tobytes())
        with self._lock:
            hit = self._d.get(key)
            if hit is not None and all(ref() is x for ref, x in zip(hit[0], [*shared, folds])):
                self._d.move_to_end(key)
                return hit[1], hit[2]
        S_rows = [S[rows] for S in shared]
        ns = shared[0].shape[1]
        SS = np.zeros((ns, ns))
        for j, S in enumerate(S_rows):
            SS += w[j] * S.T @ S
        with self._lock:
            self._d[key] = ([weakref.ref(x) for x in [*shared, folds]], S_rows, SS)
            while len(self._d) > self.size:
                self._d.popitem(last=False)
        return S_rows, SS


_SHARED_ROWS = _SharedRows()


def _heldout(r: np.ndarray, tau: np.ndarray, Fj: list, shared: list | None, local: dict | None, folds: np.ndarray,
             K: int, w: np.ndarray, evaluate: Sequence[int] | None = None,
             prior: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Held-out squared error per joint of ``r = tau - rigid`` explained by each joint's own columns
    ``Fj`` plus ``local`` {joint: (N, c) columns of that joint only} plus ``shared`` (per joint
    (N, s) columns whose coefficients all joints share), fitted on the other folds (weights ``w``
    per joint), on the folds ``evaluate`` (default all). Returns the sums of squared errors (K, n)
    and of squared torques (K, n) per fold (0 for the folds not evaluated), the coefficients
    fitted on all samples and the held-out residual (measured minus predicted) of every sample (N, n).
    ``prior``: (per joint the diagonal information of a prior at 0 on its ``Fj`` columns; the information matrix of one
    on the first shared columns: :class:`BaseCorrection`); a list of them: a list of results, the
    normal equations formed once."""
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

    def normal(f):
        rows = folds == f
        A, b = np.zeros((P, P)), np.zeros(P)
        if shared is not None:      # the shared columns' rows and block: the same for every candidate of its own joint
            S_rows, A[off[-1]:, off[-1]:] = _SHARED_ROWS.get(shared, folds, f, w, rows)
        for j in range(n):
            D = cols(j, rows)
            idx = np.arange(off[j], off[j + 1])
            A[np.ix_(idx, idx)] += w[j] * D.T @ D
            b[idx] += w[j] * D.T @ r[rows, j]
            if shared is not None:
                S = S_rows[j]
                si = np.arange(off[-1], P)
                A[np.ix_(idx, si)] += w[j] * D.T @ S
                A[np.ix_(si, idx)] += w[j] * S.T @ D
                b[si] += w[j] * S.T @ r[rows, j]
        return A, b

    def solve(A, b):
        dg = np.diag(A)
        live = dg > 1e-300
        x = np.zeros(P)
        d = 1.0 / np.sqrt(dg[live])
        x[live] = d * np.linalg.lstsq(d[:, None] * A[np.ix_(live, live)] * d[None, :], d * b[live], rcond=1e-12)[0]
        return x

    parts = [normal(f) for f in range(K)]
    data_A, data_b = sum(p[0] for p in parts), sum(p[1] for p in parts)
    out = []
    for pr in (prior if isinstance(prior, list) else [prior]):
        Pp = np.zeros((P, P))
        if pr is not None:      # priors at 0: the joints' own columns', the rigid body's correction's
            own_p, shared_p = pr
            for j, pj in enumerate(own_p or []):
                idx = off[j] + np.arange(min(pj.size, Fj[j].shape[1]))
                Pp[idx, idx] += pj[:idx.size]
            if shared_p is not None and ns:
                pi_ = np.arange(off[-1], off[-1] + shared_p.shape[0])
                Pp[np.ix_(pi_, pi_)] += shared_p
        num, den, res = np.zeros((K, n)), np.zeros((K, n)), np.zeros_like(r)
        for f in (range(K) if evaluate is None else evaluate):
            x = solve(data_A + Pp - parts[f][0], data_b - parts[f][1])
            rows = folds == f
            S_rows = _SHARED_ROWS.get(shared, folds, f, w, rows)[0] if shared is not None else None
            for j in range(n):
                pred = cols(j, rows) @ x[off[j]:off[j + 1]]
                if shared is not None:
                    pred = pred + S_rows[j] @ x[off[-1]:]
                res[rows, j] = r[rows, j] - pred
                num[f, j] = float(np.sum(res[rows, j] ** 2))
                den[f, j] = float(np.sum(tau[rows, j] ** 2))
        out.append((num, den, solve(data_A + Pp, data_b), res))
    return out if isinstance(prior, list) else out[0]


def _rel(num: np.ndarray, den: np.ndarray) -> np.ndarray:
    """Relative error per joint of per-fold sums (K, n)."""
    return np.sqrt(num.sum(0) / np.maximum(den.sum(0), 1e-300))


def _gain_t(res0: np.ndarray, res: np.ndarray, den: np.ndarray, block: np.ndarray, joints: list[int]) -> float:
    """The held-out gain of a candidate per block of held-out samples, as the log of the ratio of
    the squared errors before and after (each joint relative to its squared torque, summed over the
    candidate's joints): its mean over the blocks divided by its standard error (a t statistic; inf
    when every block gains alike). The log ratio, not the difference: an effect's size differs from
    block to block (a counterbalance between A2's angles, a thermal term between temperatures), and
    a difference would read a gain of 90 % in one block and 50 % in another as noise."""
    ids = np.unique(block[block >= 0])
    b0 = (res0[:, joints] ** 2 / np.maximum(den[joints], 1e-300)).sum(1)
    b1 = (res[:, joints] ** 2 / np.maximum(den[joints], 1e-300)).sum(1)
    g = np.array([math.log(max(float(b0[block == b].sum()), 1e-300) / max(float(b1[block == b].sum()), 1e-300))
                  for b in ids])
    if g.size < 2:
        return float("inf") if g.sum() > 0 else 0.0
    se = float(np.std(g, ddof=1)) / np.sqrt(g.size)
    return float(np.mean(g) / se) if se > 0 else (float("inf") if np.mean(g) > 0 else 0.0)


def _projection(A: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """An orthonormal basis of ``A``'s (N, k) columns and ``y`` (N,) with them taken out."""
    Q, _ = np.linalg.qr(A[:, np.any(A != 0, axis=0)]) if A.size else (np.zeros((A.shape[0], 0)), None)
    return Q, y - Q @ (Q.T @ y)


def _gains(Q: np.ndarray, e: np.ndarray, B: np.ndarray) -> np.ndarray:
    """(O,): how much each option's columns (``B``: (N, O, c)), fitted by least squares beside the
    columns ``Q`` spans, lower the squared residual ``e`` (:func:`_projection`)."""
    N, O, c = B.shape
    Bf = B.reshape(N, O * c)
    Bp = Q @ (Q.T @ Bf)
    Bp = np.subtract(Bf, Bp, out=Bp)      # in place: a grid's columns are tens of MB
    if O > 1:
        # a grid: each option's Gram matrix as a product of its samples-last copy, a few MB at a time
        # (half einsum's time); only the best option is used, so the last bits of the others' gains
        # do not matter
        G, g = np.empty((O, c, c)), np.empty((O, c))
        step = max(1, LOWPASS_VALUES // max(N * c, 1))
        for a in range(0, O, step):
            b = min(a + step, O)
            Bt = np.ascontiguousarray(Bp[:, a * c:b * c].T).reshape(b - a, c, N)
            G[a:b], g[a:b] = Bt @ Bt.transpose(0, 2, 1), Bt @ e
        tr = np.trace(G, axis1=1, axis2=2)
    else:
        Bp = Bp.reshape(N, O, c)
        G, g = np.einsum("noc,nod->ocd", Bp, Bp), np.einsum("noc,n->oc", Bp, e)
        tr = np.einsum("noc,noc->o", Bp, Bp)
    G = G + 1e-12 * np.eye(c)[None] * (1.0 + tr[:, None, None])
    return np.einsum("oc,oc->o", g, np.linalg.solve(G, g[..., None])[..., 0])


def _pick(cand: RobotCandidate, ctx: Context, A: np.ndarray, y: np.ndarray, rows: np.ndarray, opts: list,
          B: np.ndarray, prior_rows: np.ndarray | None = None, memo: "_Batches | None" = None
          ) -> tuple[dict, np.ndarray | None]:
    """The option whose columns, fitted beside ``A`` on ``rows``, explain most of ``y`` there: the
    grid's best (``B``: every option's columns, (N, O, c)), then the candidate's finer options about
    it, then its settings moved continuously within :meth:`RobotCandidate.bounds` (bounded
    Nelder-Mead on the same squared residual). ``prior_rows`` (p, A's columns): the prior the
    candidate is judged under as rows of the least squares (:func:`_prior_rows`), so the option is
    chosen with the other terms as they are held. Returns the option and its columns on every sample
    (None: the grid's own). ``memo``: the finer options' columns kept (:class:`_Batches`)."""
    from scipy.optimize import minimize

    p = 0 if prior_rows is None else prior_rows.shape[0]
    idx = np.flatnonzero(rows)

    def at(X):      # the rows, then zeros for the prior's (the candidate has no prior); copied once
        out = np.zeros((idx.size + p,) + X.shape[1:])
        np.take(X, idx, axis=0, out=out[:idx.size], mode="clip")
        return out
    Q, e = _projection(np.concatenate([A[rows], prior_rows]) if p else A[rows], at(y))
    o = int(np.argmax(_gains(Q, e, at(B))))
    opt, cols = opts[o], None
    fine = cand.refine(ctx, opt)
    if fine:
        Bf = cand.batch(ctx, fine) if memo is None else memo.batch(cand, ctx, fine)
        k = int(np.argmax(_gains(Q, e, at(Bf))))
        opt, cols = fine[k], Bf[:, k, :]
    bounds = cand.bounds(ctx, opt)
    if bounds:
        keys = list(bounds)

        seen: dict = {}

        def cost(v):        # each point once (the start is asked again below)
            key = tuple(map(float, v))
            if key not in seen:
                seen[key] = -float(_gains(Q, e, at(cand.batch(ctx, [{**opt, **dict(zip(keys, key))}])))[0])
            return seen[key]
        x0 = np.array([opt[k] for k in keys], float)
        res = minimize(cost, x0, method="Nelder-Mead", bounds=[bounds[k] for k in keys],
                       options={"xatol": 1e-4, "fatol": 1e-9 * float(e @ e), "maxfev": 60 * len(keys)})
        if res.fun < cost(x0):
            opt = {**opt, **dict(zip(keys, map(float, res.x)))}
            cols = cand.batch(ctx, [opt])[:, 0, :]
    return opt, cols


def _prior_rows(J: Sequence[int], Fj: list, local: dict, shared: list | None, prior, scale: np.ndarray) -> np.ndarray:
    """The prior of :func:`_heldout` (``prior``: the joints' own columns' diagonals, the shared
    columns' information matrix; a list: the first) as rows of a least-squares problem whose columns
    are joints ``J``'s own and local columns one block after another, then the shared ones (as
    :meth:`_Stacked.equations`): ``R`` with ``R^T R`` the prior, joint j's own rows times
    ``scale[j]`` (1 / the square root of its weight when its equation is unweighted)."""
    pr = prior[0] if isinstance(prior, list) else prior
    own_p, shared_p = pr if pr is not None else (None, None)
    widths = [Fj[j].shape[1] + (local[j].shape[1] if j in local else 0) for j in J]
    ns = 0 if shared is None else shared[0].shape[1]
    P = int(sum(widths)) + ns
    rows, at = [], 0
    for j, wd in zip(J, widths):
        pj = np.asarray(own_p[j] if own_p is not None else [], float)[:Fj[j].shape[1]]
        for i in np.flatnonzero(pj > 0):
            row = np.zeros(P)
            row[at + i] = scale[j] * math.sqrt(pj[i])
            rows.append(row)
        at += wd
    if shared_p is not None and ns:
        e, V = np.linalg.eigh(0.5 * (shared_p + shared_p.T))
        keep = e > 1e-12 * max(float(e.max()), 1e-300)
        R = np.zeros((int(keep.sum()), P))
        R[:, at:at + shared_p.shape[0]] = np.sqrt(e[keep])[:, None] * V[:, keep].T
        s = scale[J[0]] if len(J) == 1 else 1.0
        rows += list(s * R)
    return np.array(rows).reshape(-1, P)


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
    from kukaid.logs import fingerprints

    fps = set((params.get("provenance") or {}).get("log_fingerprints") or [])
    if len(logs) < 3 or not fps:
        return list(logs), []
    seen = [bool(fps.intersection(fingerprints(lg))) for lg in logs]
    if sum(not x for x in seen) < 2:
        return list(logs), []
    return ([lg for lg, x in zip(logs, seen) if not x],
            [str(lg.attrs.get("source_file") or f"log {k + 1}") for k, (lg, x) in enumerate(zip(logs, seen)) if x])


class _Fixed(RobotCandidate):
    """Fixed columns on one joint, as a candidate (:meth:`RobotCandidate.without`'s)."""

    def __init__(self, joint: int | None, cols: np.ndarray, angle_joints: Sequence[int] = ()) -> None:
        self.joint, self.name, self._cols, self._angle = joint, "fixed", cols, list(angle_joints)

    def angle_joints(self, ctx):
        return self._angle

    def columns(self, ctx, option):
        return self._cols


class _AngleTermsHeld:
    """A candidate that takes the place of the file's terms of its joint's angle, beside them instead
    (:attr:`RobotCandidate.angle_terms_optional`); everything else the candidate's."""

    without_replaces = False

    def __init__(self, cand: RobotCandidate) -> None:
        self._cand = cand

    def __getattr__(self, name):
        return getattr(self._cand, name)

    def angle_joints(self, ctx):
        return []


class _Stacked(RobotCandidate):
    """A candidate on several joints with shared coefficients seen as one equation: its joints'
    rows stacked, each joint's weighted by ``sw`` (the square root of its weight), for choosing its
    option (:func:`_pick`); its finer options and bounds the candidate's own."""

    def __init__(self, cand: RobotCandidate, joints: Sequence[int], sw: np.ndarray) -> None:
        self.cand, self.J, self.sw = cand, list(joints), np.asarray(sw, float)
        self.name, self.joint = cand.name, None

    def _stack(self, X: np.ndarray) -> np.ndarray:
        """(N, n, ...) -> (len(J) N, ...): the joints' rows one after another, weighted."""
        return np.concatenate([self.sw[j] * X[:, j] for j in self.J])

    def batch(self, ctx, options):
        return np.stack([self._stack(self.cand.columns(ctx, o)) for o in options], axis=1)

    def refine(self, ctx, option):
        return self.cand.refine(ctx, option)

    def bounds(self, ctx, option):
        return self.cand.bounds(ctx, option)

    def prior_rows(self, Fj: list, local: dict, shared: list | None, prior) -> np.ndarray:
        """The prior as rows of :meth:`equations` (:func:`_prior_rows`: the rows are weighted, the prior
        as :func:`_heldout` adds it)."""
        return _prior_rows(self.J, Fj, local, shared, prior, np.ones(len(Fj)))

    def equations(self, Fj: list, local: dict, shared: list | None, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The stacked equations' columns (each joint's own and local columns a block of their own,
        the shared ones in common) and right-hand side."""
        N = r.shape[0]
        own = [np.concatenate([Fj[j]] + ([local[j]] if j in local else []), axis=1) for j in self.J]
        width = sum(o.shape[1] for o in own)
        ns = 0 if shared is None else shared[0].shape[1]
        A = np.zeros((len(self.J) * N, width + ns))
        at = 0
        for k, (j, o) in enumerate(zip(self.J, own)):
            rows = slice(k * N, (k + 1) * N)
            A[rows, at:at + o.shape[1]] = self.sw[j] * o
            if ns:
                A[rows, width:] = self.sw[j] * shared[j]
            at += o.shape[1]
        return A, np.concatenate([self.sw[j] * r[:, j] for j in self.J])


def _try(cand: RobotCandidate, ctx: Context, r, tau, Fjs: dict, shared, local, folds, K, w, held, prior, base=None,
         admissible=None, memo: "_Batches | None" = None, pick_prior=None):
    """:func:`_try_at` at each prior strength of ``Fjs`` {multiple of the raw ``prior``: the joints'
    own columns chosen at it}: the one with the smallest weighted held-out error, and that strength
    (None when no option applies). With and without the candidate, the model is judged at the
    strength that predicts it best. ``admissible(num, den)``: the strengths whose held-out errors it
    accepts (no joint made worse) are preferred; none accepted, the best of all. ``memo``: the
    candidate's columns kept from one strength to the next (:class:`_Batches`; default: a new one).
    ``pick_prior``: the raw prior its options are chosen under (default ``prior``), at each strength."""
    best, best_ok = None, None
    memo = _Batches() if memo is None else memo
    for c, Fj in Fjs.items():
        res = _try_at(cand, ctx, r, tau, Fj, shared, local, folds, K, w, held, _scaled(prior, c), base, memo,
                      None if pick_prior is None else _scaled(pick_prior, c))
        if res is None:
            return None
        e = _weighted(res[0], w)
        if best is None or e < best[0]:
            best = (e, res + (c,))
        if admissible is not None and admissible(res[0], res[1]) and (best_ok is None or e < best_ok[0]):
            best_ok = (e, res + (c,))
    return (best_ok or best)[1]


def _short_of_margin(before: float, after: float, ref: float, without_what: str) -> str:
    """Why a candidate whose held-out error ``after`` is not ``MARGIN`` below ``ref`` is not named: ``ref`` the
    baseline's error ``before``, or, when lower, the candidate's without what names it (``without_what``), the drop
    then measured from it (LWR4+ A1: 26.14 -> 23.20 % "needs a 5 % drop" read as an 11 % drop refused)."""
    said = f"held-out error {100 * before:.2f} -> {100 * after:.2f} % (needs a {100 * MARGIN:.0f} % drop"
    if ref < before:
        return f"{said} from {100 * ref:.2f} %, its error without {without_what})"
    return said + ")"


def _worse(e: np.ndarray, err: np.ndarray, rms: np.ndarray, floor: np.ndarray) -> list[int]:
    """The joints (0-based) a model of held-out relative errors ``e`` makes worse than ``err``: by
    :data:`MARGIN` and by more than :data:`WORSE_FLOOR` of the joint's noise floor (with the rigid
    body refitted beside a candidate, every joint's held-out error moves a little)."""
    return [k for k in range(e.size)
            if e[k] > (1 + MARGIN) * err[k] + 1e-12 and (e[k] - err[k]) * rms[k] > WORSE_FLOOR * floor[k]]


def _try_at(cand: RobotCandidate, ctx: Context, r, tau, Fj, shared, local, folds, K, w, held, prior, base=None,
            memo: "_Batches | None" = None, pick_prior=None):
    """Held-out relative error per joint with the candidate, its options chosen on the training folds;
    the option chosen on all samples and the candidate's coefficients fitted on all samples (None
    when no option applies). ``prior`` a list of priors: a list of results (options chosen once).
    ``memo``: its options' columns kept (:class:`_Batches`). ``pick_prior``: the prior the options
    are chosen under (default ``prior``: :func:`_prior_rows`).
    """
    pp = prior if pick_prior is None else pick_prior
    n = r.shape[1]
    opts = cand.options(ctx)
    if not opts:
        return None
    for jj in (cand.angle_joints(ctx) if base is not None else []):
        r, Fj = base.without_angle_terms(jj, r, Fj)
    for jj in (cand.friction_joints(ctx) if base is not None else []):
        Fj = base.without_friction(jj, Fj)
    if len(opts) == 1:
        pick, best_all = [0] * K, 0
        B = cand.columns(ctx, opts[0])
        B = B[:, None, :] if B.ndim == 2 else None
    else:
        j = cand.joint
        if j is None:
            # a term on several joints with shared coefficients: the option by least squares of their
            # equations stacked (each weighted as the fit weighs it)
            view = _Stacked(cand, cand.joints(ctx), np.sqrt(w))
            A, y = view.equations(Fj, local, shared, r)
            Pr = view.prior_rows(Fj, local, shared, pp) if PICK_WITH_PRIOR else None
            B = view.batch(ctx, opts) if memo is None else memo.batch(view, ctx, opts, grid=True)
        else:
            view = cand
            B = cand.batch(ctx, opts) if memo is None else memo.batch(cand, ctx, opts, grid=True)
            # the option by least squares of the joint's own terms and the shared ones (the rigid body's
            # correction among them) on the joint's equation
            parts = [Fj[j]] + ([local[j]] if j in local else []) + ([shared[j]] if shared is not None else [])
            A, y = np.concatenate(parts, axis=1), r[:, j]
            Pr = _prior_rows([j], Fj, local, shared, pp, np.full(n, 1.0 / math.sqrt(w[j]))) if PICK_WITH_PRIOR \
                else None

        def pick_on(rows):
            opt, cols = _pick(view, ctx, A, y, np.tile(rows, y.size // rows.size), opts, B, Pr, memo)
            if cols is None:
                return opts.index(opt)
            extra.append((opt, cols))
            return len(opts) + len(extra) - 1

        extra: list = []
        best_all = pick_on(np.ones(r.shape[0], bool))
        pick = [pick_on(folds != f) if f in held else -1 for f in range(K)]
        opts = opts + [e[0] for e in extra]
        if j is None:       # the columns of the options picked, on every joint
            B = None
        else:
            B = np.concatenate([B] + [e[1][:, None, :] for e in extra], axis=1) if extra else B

    def cols_of(o):
        return B[:, o, :] if B is not None else cand.columns(ctx, opts[o])

    many = isinstance(prior, list)
    priors = prior if many else [prior]
    acc = [[np.zeros((K, n)), np.zeros((K, n)), np.zeros_like(r)] for _ in priors]
    for o in sorted(set(pick[f] for f in held)):
        loc, sh = _with(local, shared, cand, cols_of(o), n)
        for a_, (a, b, _, res_o) in zip(acc, _heldout(r, tau, Fj, sh, loc, folds, K, w,
                                                    [f for f in held if pick[f] == o], prior=priors)):
            a_[0], a_[1], a_[2] = a_[0] + a, a_[1] + b, a_[2] + res_o
    loc, sh = _with(local, shared, cand, cols_of(best_all), n)
    c = cols_of(best_all).shape[-1]
    out = []
    for a_, (_, _, x, _) in zip(acc, _heldout(r, tau, Fj, sh, loc, folds, K, w, [], prior=priors)):
        if cand.joint is None:
            coefs = x[-c:]
        else:
            j = cand.joint
            end = sum(F.shape[1] + (loc[i].shape[1] if i in loc else 0) for i, F in enumerate(Fj[:j + 1]))
            coefs = x[end - c:end]
        out.append((a_[0], a_[1], a_[2], opts[best_all], coefs, cols_of(best_all)))
    return out if many else out[0]


@dataclass
class _State:
    """Where the diagnosis stands after the effects named so far: the residual torque ``r`` (N, n) the
    joints' own columns take on (``Fj`` at the prior strength ``scale``, ``Fjs`` at each), the named
    effects' columns (``local`` per joint, ``shared`` by all), the prior, the held-out relative error
    per joint ``err``, its squared error per fold ``fold_err`` (K, n) and residual ``res0`` (N, n), and
    the joints whose terms of their own angle a named effect took the place of."""

    r: np.ndarray
    Fj: list
    Fjs: dict
    scale: float
    shared: Any
    local: dict
    prior: Any
    err: np.ndarray
    fold_err: np.ndarray
    res0: np.ndarray
    replaced: list


@dataclass
class _Trial:
    """One candidate tried given a :class:`_State`: the way it was tried (``var``), its joints, the
    held-out mean relative error of them before and with it (``mb``, ``ma``), its squared error per fold and residual, its columns, prior strength, option and coefficients,
    its gain in standard errors, why it is not named (None: it may be; ``no_gain``: for want of a
    held-out gain) and the evidence the result reports."""

    name: str
    cand: RobotCandidate
    var: Any
    joints: list
    mb: float
    ma: float
    fnum: np.ndarray
    fres: np.ndarray
    col: np.ndarray
    scale: float
    opt: dict
    coefs: np.ndarray
    gain_t: float
    reason: str | None
    no_gain: bool
    evidence: dict


def _undetermined_note(best: _Trial, others: Sequence[_Trial]) -> dict:
    """What a step that stands for an undetermined mechanism says: the candidates, the one modelled
    (the larger held-out gain), each one's held-out error of its joints alone, and what would settle it."""
    from kukaid.diagnose.ambiguity import settled_by

    names = [best.name] + [t.name for t in others]
    return {"candidates": names, "modelled_as": best.name,
            "heldout_relative_error": {t.name: t.ma for t in (best, *others)},
            "settled_by": settled_by(names, best.name)}


def diagnose_robot(params: dict, logs: Sequence[Any], robot=None, *, max_steps: int = 3) -> RobotDiagnosis:
    """Find the effects of :mod:`this module`'s candidates that the logs show and the robot file
    misses (see the module's text). ``params``: a validated ``kukaid.robot_params/1`` dictionary."""
    from kukaid.identify.robot_fit import _one_blas_thread

    with _one_blas_thread():     # narrow products: BLAS threads only wait for cores
        return _diagnose_robot(params, logs, robot, max_steps=max_steps)


def _diagnose_robot(params: dict, logs: Sequence[Any], robot=None, *, max_steps: int = 3) -> RobotDiagnosis:
    from kukaid.identify.robot_fit import _folds
    from kukaid.models.robot import RobotModel

    robot = robot or RobotModel(params["robot"]["urdf"])
    check_fitted_urdf(params, robot.sha256, robot.path)
    if not logs:
        raise KukaidError("diagnose: no logs")
    logs, fitted_on = _unseen(params, logs)
    m, rigid, base, tau_hat, pieces, corr, B, floor, own_signals = _signals(params, logs, robot)
    prior = (base.prior, B.prior)          # own columns' diagonals; (information, payload part)

    def prior_of(cand, pr, pick: bool = False):
        """The prior ``pr`` as a candidate is judged under it: a counterbalance's frees the gravity
        parameters of the links its joint carries (:meth:`BaseCorrection.freed`), the wrist's coupled
        friction the inertial parameters of the wrist's links (:meth:`BaseCorrection.freed_inertia`).
        ``pick``: the prior its options are chosen under, the last link's first moments held."""
        if cand.frees_gravity:
            pr = (pr[0], B.freed(pr[1], cand.joint))
        links = cand.freed_links(ctx)
        if links:
            pr = (pr[0], B.freed_inertia(pr[1], links, moments=not pick))
        return pr
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
    # the baseline's choices at each prior strength; the strength whose baseline predicts best
    bl = _baselines(base, r, tau, corr, prior, folds, K, w)
    Fjs = {c: v[0] for c, v in bl.items()}
    scale = min(bl, key=lambda c: _weighted(bl[c][2], w))
    Fj, choice = bl[scale][:2]
    ctx = _context(pieces, base, choice)
    # joints that carry gravity over the data: a counterbalance candidate each
    # (a counterbalance sits on a joint that carries the most gravity: at least half the largest range)
    g = ctx.gravity
    span = np.ptp(g, axis=0)
    grav = [j for j in range(n) if span[j] >= 0.5 * span.max() and np.std(g[:, j]) > 0.1 * np.sqrt(np.mean(tau[:, j] ** 2))]
    given = params.get("effects") or {}     # the file's own effects are held, never named again
    remaining = {c.name: c for c in robot_candidates(ctx, grav) if c.name not in given}
    local: dict = {}
    shared = corr
    num, den, _, res0 = _heldout(r, tau, Fj, shared, local, folds, K, w, held, prior=_scaled(prior, scale))
    # blocks of the held-out samples (FOLDS contiguous blocks of each held-out recording, or the
    # blocks themselves): a named effect's held-out gain must stand out from its spread over them
    block = np.full(r.shape[0], -1)
    for f in held:
        idx = np.flatnonzero(folds == f)
        nb = FOLDS if K > 1 else 1
        block[idx] = f * FOLDS + np.minimum(np.arange(idx.size) * nb // max(idx.size, 1), nb - 1)
    before = _rel(num, den)

    def judge(name: str, cand, st: _State) -> _Trial | None:
        """The candidate tried given the state ``st`` (the effects named so far): its held-out figures,
        and why it is not named (None: it may be)."""
        # a counterbalance, a payload or the wrist's coupled friction is judged at every prior
        # strength (a rigid body refitted freely takes part of either in, held it keeps what the
        # file took in), preferring those that make no joint worse; the others at the baseline's
        pr = prior_of(cand, st.prior)
        # its options (the wrist's ratios) are chosen with the last link's first moments held: free,
        # they trade with a motor's Coulomb column where they are chosen (six-axis virtual KR C4,
        # wrist seed 61: c65 -0.443 for -0.377, A6 held out 14x the noise floor, held 3.4x)
        pick = prior_of(cand, st.prior, pick=True)
        err = st.err
        # a candidate that may take the place of the file's terms of its joint's angle is tried
        # in their place and beside them: the better by held-out error
        res, var, ways = None, cand, []
        memo = _Batches()       # its grid's columns, the same each way and at each strength
        for v in [cand] + ([_AngleTermsHeld(cand)] if cand.angle_terms_optional else []):
            rv = _try(v, ctx, st.r, tau, st.Fjs if cand.rigid_body_like else {st.scale: st.Fj}, st.shared, st.local,
                      folds, K, w, held, pr, base, admissible=lambda a, b: not _worse(_rel(a, b), err, rms, floor),
                      memo=memo, pick_prior=pick)
            if rv is not None:
                ways.append(v)
            if rv is not None and (res is None or _weighted(rv[0], w) < _weighted(res[0], w)):
                res, var = rv, v
        if res is None:
            return None
        fnum, fden, fres, opt, coefs, col, c_scale = res
        e = _rel(fnum, fden)
        joints = cand.joints(ctx)
        mb, ma = float(np.mean(err[joints])), float(np.mean(e[joints]))
        # judged against the baseline, and against the candidate without what names it when that
        # predicts better (a thermal friction's own friction terms without the temperature). A
        # candidate tried in several ways (in the place of the file's terms of its joint's angle
        # and beside them, the better by held-out error) is judged against its null tried in each
        # of those ways too, the better of them: the null given the same freedom, so that taking
        # the file's terms out is not what names it (a clean whole-arm log of the fleet tests:
        # A5's file terms out alone held A5 out 2 % better, the ripple beside them 7 %, a noise
        # peak of 0.013 N·m at order 25.6 rad/rad, half the noise floor, named)
        ref, ref_res, without = mb, st.res0, cand.without(ctx, opt)
        if without is not None:
            for aj in dict.fromkeys(tuple(v.angle_joints(ctx)) if v.without_replaces else () for v in ways):
                wnum, _, wres = _try_at(_Fixed(cand.joint, without, aj), ctx, st.r, tau,
                                        st.Fjs[c_scale] if cand.rigid_body_like else st.Fj, st.shared, st.local,
                                        folds, K, w, held, _scaled(pr, c_scale), base)[:3]
                if float(np.mean(_rel(wnum, den)[joints])) < ref:
                    ref, ref_res = float(np.mean(_rel(wnum, den)[joints])), wres
        gain_t = _gain_t(ref_res, fres, den.sum(0), block, joints)
        per_fold = (fnum[held][:, joints].sum(1) / np.maximum(st.fold_err[held][:, joints].sum(1), 1e-300)).tolist()
        # worse: by the margin and by more than WORSE_FLOOR of the joint's noise floor (:func:`_worse`)
        worse = [f"A{k + 1} ({100 * err[k]:.2f} -> {100 * e[k]:.2f} %)" for k in _worse(e, err, rms, floor)]
        reason, no_gain = None, False
        if ma > (1 - MARGIN) * ref:
            no_gain = True
            reason = _short_of_margin(mb, ma, ref, cand.without_what)
        elif worse:
            reason = f"makes {', '.join(worse)} worse on held-out data"
        elif gain_t < MIN_T:
            no_gain = True
            reason = (f"held-out error {100 * mb:.2f} -> {100 * ma:.2f} %, but the gain is {gain_t:.2g} x its "
                      f"standard error over the held-out blocks (needs {MIN_T:g})")
        else:
            reason = cand.implausible(ctx, opt, coefs) or None
        return _Trial(name=name, cand=cand, var=var, joints=joints, mb=mb, ma=ma, fnum=fnum, fres=fres,
                      col=col, scale=c_scale, opt=opt, coefs=coefs, gain_t=gain_t, reason=reason, no_gain=no_gain,
                      evidence={"name": name, "mean_before": mb, "mean_after": ma, "fold_sse_ratio": per_fold,
                                "gain_t": gain_t})

    def named_in(st: _State, t: _Trial) -> _State:
        """The state with ``t``'s effect named: its columns beside the file's terms (in the place of
        its joint's angle terms where it was tried so), its prior, the joints' own choices and the
        prior's strength made again with it beside (made without it, they were made on a torque it
        dominated: a ripple of 30x the noise floor on a joint leaves its Coulomb transition, viscous
        form and rotor inertia to chance), kept where they predict better than the trial's own."""
        Fj_, scale_, fnum, fres = st.Fjs[t.scale], t.scale, t.fnum, t.fres
        local_, shared_ = _with(st.local, st.shared, t.cand, t.col, n)
        r_, replaced_ = st.r, list(st.replaced)
        for jj in t.var.angle_joints(ctx):
            r_, Fj_ = base.without_angle_terms(jj, r_, Fj_)
            replaced_ += [jj] if jj not in replaced_ else []
        prior_ = prior_of(t.cand, st.prior)
        e_now = _weighted(fnum, w)
        bl_ = _baselines(base, r_, tau, shared_, prior_, folds, K, w, local_, replaced_)
        for c, (Fc_, _, num_c, res_c) in bl_.items():
            if _weighted(num_c, w) < e_now:
                e_now, Fj_, scale_, fnum, fres = _weighted(num_c, w), Fc_, c, num_c, res_c
        return _State(r=r_, Fj=Fj_, Fjs={c: v[0] for c, v in bl_.items()}, scale=scale_, shared=shared_,
                      local=local_, prior=prior_, err=_rel(fnum, den), fold_err=fnum, res0=fres, replaced=replaced_)

    st = _State(r=r, Fj=Fj, Fjs=Fjs, scale=scale, shared=shared, local=local, prior=prior, err=before.copy(),
                fold_err=num, res0=res0, replaced=[])
    steps, rejected = [], []
    tried: list[dict] = []
    named: list = []                        # (candidate, its option) in the order named
    kept: dict = {}                         # named effects the refined file keeps at the diagnosis' coefficients
    residuals = [res0]                      # held-out residual (N, n) at the start and after each step
    given_best: dict[str, _Trial | None] = {}   # candidates already tried given the last named effect
    for rnd in range(max(0, max_steps)):
        trials = {name: given_best[name] if name in given_best else judge(name, cand, st)
                  for name, cand in remaining.items()}
        trials = {k: t for k, t in trials.items() if t is not None}
        if rnd == 0:
            tried = [t.evidence for t in trials.values()]
        for t in trials.values():
            if t.reason is not None:
                rejected = [x_ for x_ in rejected if x_["name"] != t.name] + [{"name": t.name, "reason": t.reason}]
        passing = [t for t in trials.values() if t.reason is None]
        if not passing:
            break
        best = max(passing, key=lambda t: (t.mb - t.ma) / t.mb)
        remaining.pop(best.name)
        named.append((best.cand, best.opt))
        if best.cand.held_in_refit:
            kept[best.name] = np.asarray(best.coefs, float)
        rejected = [x_ for x_ in rejected if x_["name"] != best.name]
        new = named_in(st, best)
        # a candidate the round let pass too, on the best's joints, whose held-out error the data do not
        # tell from the best's: when neither adds to the other, both explain the same residual
        given_best, undetermined = {}, []
        for t in passing:
            if t is best or not set(t.joints) & set(best.joints) or _gain_t(
                    t.fres, best.fres, den.sum(0), block, sorted(set(t.joints) | set(best.joints))) >= MIN_T:
                continue
            given_best[t.name] = after = judge(t.name, t.cand, new)
            if after is None or after.no_gain:
                back = judge(best.name, best.cand, named_in(st, t))
                if back is None or back.no_gain:
                    undetermined.append(t)
        for t in undetermined:
            remaining.pop(t.name)
            rejected = [x_ for x_ in rejected if x_["name"] != t.name] + [{"name": t.name, "reason": (
                f"explains the same held-out residual as {best.name}, which is modelled (mechanism undetermined)")}]
        info = best.cand.describe(ctx, best.opt, best.coefs)
        joints = best.joints
        ma = float(np.mean(new.err[joints]))
        step = {"name": best.name, "joints": [f"A{k + 1}" for k in joints], "params": {
            k: v for k, v in info.items() if not isinstance(v, list)}, "details": info,
            "mean_before": best.mb, "mean_after": ma, "gain_t": best.gain_t, "heldout_before": st.err.tolist(),
            "heldout_after": new.err.tolist(), "trials": [t.evidence for t in trials.values()], "option": best.opt}
        if undetermined:
            step["undetermined"] = _undetermined_note(best, undetermined)
        steps.append(step)
        st = new
        residuals.append(st.res0)
    refined = _refined(params, logs, base, own_signals, named, st.r, tau, corr, _scaled(st.prior, st.scale), w,
                       st.replaced, kept)
    if any("undetermined" in s for s in steps):     # as the one-axis diagnosis writes it
        refined["provenance"]["diagnose"]["undetermined"] = [
            {k: s["undetermined"][k] for k in ("candidates", "modelled_as", "settled_by")}
            for s in steps if "undetermined" in s]
    return RobotDiagnosis(axes=axes, folds=how, before=before.tolist(), after=st.err.tolist(), steps=steps,
                          rejected=rejected, in_sample=in_sample, noise_floor=floor.tolist(), rms=rms.tolist(),
                          smooth=[any(smooth_at_source(lg.tau[:, lg.index(a)]) for lg in logs) for a in axes],
                          tried=tried, fitted_on=fitted_on, given=list(given), params=refined, tested=max_steps > 0,
                          series=Series(time=pieces["time"], log_rows=tuple(pieces["log_rows"]), signals=own_signals,
                                        residuals=residuals))


def _refined(params: dict, logs: Sequence[Any], base: _Baseline, own, named: list, r, tau, corr, prior, w,
             replaced: Sequence[int], kept: dict | None = None) -> dict:
    """The parameter file with the named effects in it (``effects``: :mod:`kukaid.models.robot_effects`),
    as it predicts: its own terms (its Coulomb column and held viscous term, as the file has them)
    and the rigid body's correction (under the prior at the strength the diagnosis ended on: the
    file's uncertainty) refitted beside the effects' columns on every sample of the diagnosis (the
    file's effects held). A counterbalance's joint has its spring and ripple terms at 0 (it takes
    their place). The file as it was when nothing is named. ``own``: the file's signals
    (:class:`~kukaid.models.robot_effects.EffectSignals`); ``kept``: {name: coefficients} of named
    effects kept as the diagnosis found them, their torque taken from the data before the refit (a
    gear elasticity: refitted with the file's own columns it is not determined and can come out
    negative)."""
    import copy

    from kukaid.logs import log_fingerprint
    from kukaid.models import robot_effects

    out = copy.deepcopy(params)
    if not named:
        return out
    n = r.shape[1]
    Fj = [base.cols(j, base.coulomb.shape[2] - 1, "hold", rotor=False) for j in range(n)]
    for j in replaced:
        Fj = base.without_angle_terms(j, r, Fj)[1]
    local, shared, cols = {}, corr, []
    kept = kept or {}
    r = r.copy()
    for cand, opt in named:
        col = robot_effects.columns(cand.name, opt, own)
        if cand.name in kept:       # its torque taken out, its coefficients kept
            if col.ndim == 3:
                r -= col @ kept[cand.name]
            else:
                r[:, cand.joint] -= col @ kept[cand.name]
            cols.append(0)
            continue
        local, shared = _with(local, shared, cand, col, n)
        cols.append(col.shape[-1])
    x = _heldout(r, tau, Fj, shared, local, np.zeros(r.shape[0], int), 1, w, [], prior=prior)[2]
    vals = out["friction"]["values"]
    at, coefs = 0, {}
    for j in range(n):
        for k, v in zip(base.names[j], x[at:at + len(base.names[j])]):
            angle = k.endswith(".k") or ".ripple_" in k     # fitted as a change from the file's value
            vals[k] = float(v) + (vals[k] if angle and j not in replaced else 0.0)
        at += Fj[j].shape[1]
        for (cand, _), c in zip(named, cols):
            if cand.joint == j and cand.name not in kept:
                coefs[cand.name], at = x[at:at + c], at + c
    bp = out["base_parameters"]
    size = corr[0].shape[1]
    bp["values"] = (np.asarray(bp["values"], float) + x[at:at + size]).tolist()
    at += size
    for (cand, _), c in zip(named, cols):
        if cand.joint is None and cand.name not in kept:
            coefs[cand.name], at = x[at:at + c], at + c
    coefs.update(kept)
    out["effects"] = {**(params.get("effects") or {}),
                      **{cand.name: {**opt, "coefficients": coefs[cand.name].tolist()} for cand, opt in named}}
    prov = out.setdefault("provenance", {}) or {}
    names = [str(lg.attrs.get("source_file", "")) for lg in logs]
    prov["logs"] = list(dict.fromkeys([*(prov.get("logs") or []), *names]))
    prov["log_fingerprints"] = list(dict.fromkeys([*(prov.get("log_fingerprints") or []),
                                                   *(log_fingerprint(lg) for lg in logs)]))
    prov["diagnose"] = {"effects_added": [cand.name for cand, _ in named], "refitted_on": names,
                        "refitted": "friction values, base_parameters.values (under the file's uncertainty); "
                                    "standard_parameters, sigma and metrics are the fit's"}
    out["provenance"] = prov
    return out
