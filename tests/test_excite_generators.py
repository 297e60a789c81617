"""Excitation trajectories: speeds, periods, limits, JSON round trip, malformed files."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from kukaid.errors import KukaidError, LimitError
from kukaid.excite import (IPO_DT, KINDS, AxisLimits, Trajectory, TrajectoryError, friction, generate, inertia,
                           presliding, validation)

DEG = math.pi / 180


def test_every_kind_is_sampled_at_the_ipo_rate_inside_the_default_limits():
    lim = AxisLimits.kr6_r700_sixx(3)
    assert lim.q_min == pytest.approx(-120 * DEG) and lim.q_max == pytest.approx(156 * DEG)
    assert lim.qd_max == pytest.approx(360 * DEG)
    for kind in KINDS:
        tr = generate(kind)
        assert tr.kind == kind and tr.axis == 3
        assert np.allclose(np.diff(tr.t), IPO_DT)
        assert tr.t[0] == 0.0
        assert lim.violations(tr) == []
        # starts and ends at rest
        assert abs(tr.qd[0]) < 1e-9 and abs(tr.qd[-1]) < 1e-9
        # centred in A3's range by default
        mid = 0.5 * (lim.q_min + lim.q_max)
        assert abs(0.5 * (tr.q.min() + tr.q.max()) - mid) < 0.3


def test_friction_plateaus_have_the_asked_speeds_in_both_directions():
    speeds = [0.02, 0.1, 0.5]
    tr = friction(speeds=speeds, plateau=2.0, settle=0.5)
    plateaus = tr.params["plateaus"]
    assert len(plateaus) == 2 * len(speeds)
    seen = []
    for t0, t1, v in plateaus:
        m = (tr.t > t0 + 1e-6) & (tr.t < t1 - 1e-6)
        assert m.sum() >= 40  # long enough to average
        # constant velocity on the plateau: measured by differences of the sampled positions
        qd = np.diff(tr.q[m]) / IPO_DT
        assert np.allclose(qd, v, rtol=1e-6, atol=1e-9)
        seen.append(v)
    assert sorted(seen) == pytest.approx(sorted([s for v in speeds for s in (v, -v)]))
    # each pair (+v, -v) covers the same positions (Γf = (Γ+ - Γ-)/2 at equal q)
    for (a0, a1, va), (b0, b1, vb) in zip(plateaus[0::2], plateaus[1::2]):
        assert va == -vb
        qa = tr.q[(tr.t >= a0) & (tr.t <= a1)]
        qb = tr.q[(tr.t >= b0) & (tr.t <= b1)]
        overlap = min(qa.max(), qb.max()) - max(qa.min(), qb.min())
        assert overlap > 0.8 * (qa.max() - qa.min())


def test_friction_default_speeds_are_log_spaced_from_below_vs_to_1_rad_s():
    tr = friction()
    v = np.array(tr.params["speeds"])
    assert 8 <= v.size <= 12
    assert v[0] <= 0.02 and v[-1] == pytest.approx(1.0)
    assert np.allclose(np.diff(np.log(v)), np.log(v[1] / v[0]))
    # standstill (settle) between moves
    still = np.abs(np.diff(tr.q)) < 1e-12
    assert still.sum() * IPO_DT > len(v) * 2 * 0.9


def test_friction_acceleration_is_smooth_and_limited():
    tr = friction(speeds=[0.3, 1.0], acc=2.0)
    assert np.max(np.abs(tr.qdd)) <= 2.0 * 1.01
    jerk = np.diff(tr.qdd) / IPO_DT
    assert np.max(np.abs(jerk)) < 30  # continuous acceleration (cosine ramps), no steps


def test_inertia_sine_has_the_asked_period_and_periods():
    tr = inertia(period=3.0, n_periods=4, amplitude=0.5)
    t0, t1 = tr.params["full_amplitude"]
    assert t1 - t0 == pytest.approx(12.0)
    m = (tr.t >= t0) & (tr.t <= t1)
    x = tr.q[m] - tr.params["centre"]
    # spectrum peak at 1/period
    f = np.fft.rfftfreq(8 * x.size, IPO_DT)
    spec = np.abs(np.fft.rfft(x, 8 * x.size))
    assert f[np.argmax(spec)] == pytest.approx(1 / 3.0, rel=0.02)
    assert np.max(np.abs(x)) == pytest.approx(0.5, rel=1e-3)
    # upward zero crossings one period apart
    s = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))
    assert np.allclose(np.diff(tr.t[m][s]), 3.0, atol=2 * IPO_DT)
    # ramped in and out: the envelope starts and ends at rest
    assert abs(tr.qd[0]) < 1e-9 and np.max(np.abs(tr.qdd)) < 0.5 * (2 * np.pi / 3) ** 2 * 1.6


def test_inertia_needs_three_periods():
    with pytest.raises(TrajectoryError, match="n_periods"):
        inertia(n_periods=2)


def test_presliding_moves_about_a_degree_then_reverses_with_decreasing_amplitude():
    tr = presliding()
    stop_t, stop_q = tr.params["stop_time"], tr.params["stop_q"]
    i = np.searchsorted(tr.t, stop_t)
    assert tr.q[i] - tr.q[0] == pytest.approx(1 * DEG, abs=1e-9)
    hold = (tr.t >= stop_t) & (tr.t <= stop_t + tr.params["hold"])
    assert np.ptp(tr.q[hold]) < 1e-12
    # excursions around the stop position: alternating sign, decreasing size
    after = tr.t > stop_t + tr.params["hold"]
    x = tr.q[after] - stop_q
    ext = [x[np.argmax(np.abs(x))]]
    amps = tr.params["reversals"]
    assert ext[0] == pytest.approx(-amps[0], rel=1e-6)
    assert all(a > b for a, b in zip(amps, amps[1:]))
    assert amps[0] > 2 * 7.3406 / 35894  # beyond the saturation of the paper's largest element
    # quasi-static: slower than qd_thr = 0.0017 rad/s
    assert np.max(np.abs(tr.qd[after])) < 0.0017
    assert tr.q[-1] == pytest.approx(stop_q)


def test_validation_mixes_sines_and_moves():
    tr = validation()
    n = len(tr.params["moves"])
    still = np.abs(np.diff(tr.q)) < 1e-12
    starts = np.flatnonzero(still[1:] & ~still[:-1])
    assert starts.size >= n  # standstill after each move
    assert np.ptp(tr.q) > 0.5


def test_limit_refusal_names_the_limit_the_value_and_the_time():
    with pytest.raises(LimitError, match=r"velocity limit of A3: \|qd\| = 7 rad/s .* at t = \d+\.\d+ s"):
        friction(speeds=[7.0], span=4.5, acc=20.0)
    with pytest.raises(TrajectoryError, match="8 rad/s cannot be reached"):
        friction(speeds=[8.0], span=4.0, acc=8.0)
    with pytest.raises(LimitError, match=r"position limit of A3: .* at t = .* (below|above)"):
        inertia(amplitude=2.5)
    with pytest.raises(LimitError, match="acceleration limit"):
        inertia(amplitude=0.8, period=1.0)
    lim = AxisLimits.from_dict({"qd_max_deg": 30.0})
    with pytest.raises(LimitError, match=r"velocity limit of A3: \|qd\| = 1 rad/s \(57.3 deg/s\)"):
        friction(speeds=[1.0], limits=lim)


def test_limits_from_dict_and_bad_limits():
    lim = AxisLimits.from_dict({"q_min_deg": -10, "q_max": 0.5, "qdd_max": 3})
    assert lim.q_min == pytest.approx(-10 * DEG) and lim.q_max == 0.5 and lim.qdd_max == 3
    assert lim.qd_max == pytest.approx(360 * DEG)
    with pytest.raises(TrajectoryError, match="unknown key 'speed'"):
        AxisLimits.from_dict({"speed": 1})
    with pytest.raises(TrajectoryError, match="q_min .* must be below q_max"):
        AxisLimits.from_dict({"q_min": 1.0, "q_max": 0.5})


def test_bad_generator_options_are_named():
    with pytest.raises(TrajectoryError, match="option speeds"):
        friction(speeds=[0.1, -0.2])
    with pytest.raises(TrajectoryError, match="option period"):
        inertia(period=0)
    with pytest.raises(TrajectoryError, match="option move_speeds"):
        validation(moves=[0.1], move_speeds=[0.1, 0.2])
    with pytest.raises(KukaidError, match="unknown experiment kind"):
        generate("wobble")


def test_json_round_trip(tmp_path):
    tr = friction(speeds=[0.05, 0.2], plateau=1.0)
    p = tmp_path / "traj.json"
    tr.to_json(p)
    d = json.loads(p.read_text())
    assert d["schema"] == "kukaid.trajectory/1" and d["kind"] == "friction" and d["axis"] == 3
    back = Trajectory.from_json(p)
    assert np.array_equal(back.t, tr.t) and np.array_equal(back.q, tr.q)
    assert back.params == json.loads(json.dumps(tr.params))
    assert back.limits == tr.limits and back.kind == tr.kind and back.axis == tr.axis


@pytest.mark.parametrize("content, message", [
    ("", "empty file"),
    ("{\"schema\": ", r"not valid JSON \(line 1"),
    ("[1, 2]", "expected a JSON object"),
    ('{"schema": "other/1", "t": [0, 1], "q": [0, 0]}', "field 'schema'"),
    ('{"schema": "kukaid.trajectory/1", "q": [0, 0]}', "missing field 't'"),
    ('{"schema": "kukaid.trajectory/1", "t": [0, 0.012], "q": [0, "a"]}', r"field 'q' must be a list of numbers \(element 1"),
    ('{"schema": "kukaid.trajectory/1", "t": [0, 0.012, 0.024], "q": [0, 0]}', "'t' has 3 samples but 'q' has 2"),
    ('{"schema": "kukaid.trajectory/1", "t": [0, 0.012, 0.012], "q": [0, 0, 0]}', "not strictly increasing at index 2"),
    ('{"schema": "kukaid.trajectory/1", "t": [0, 0.012, 0.03], "q": [0, 0, 0]}', "not uniformly sampled at index 2"),
    ('{"schema": "kukaid.trajectory/1", "t": [0, 0.012], "q": [0, 0], "axis": 13}', "field 'axis'"),
    ('{"schema": "kukaid.trajectory/1", "t": [0, 0.012], "q": [0, 0], "units": {"q": "deg"}}', "field 'units'"),
    ('{"schema": "kukaid.trajectory/1", "t": [0], "q": [0]}', "too few samples"),
])
def test_bad_trajectory_json_gives_one_line_error(tmp_path, content, message):
    p = tmp_path / "bad.json"
    p.write_text(content)
    with pytest.raises(TrajectoryError, match=message) as e:
        Trajectory.from_json(p)
    assert "\n" not in str(e.value) and str(p) in str(e.value)


def test_trajectory_unpacks_and_is_duck_typed():
    tr = inertia()
    t, q = tr
    assert t is tr.t and q is tr.q
