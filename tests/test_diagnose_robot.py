"""`kukaid diagnose --params robot.json`: the robot's candidates (an A2 gas counterbalance, a payload
at the flange) named on held-out recordings when the logs show them, nothing on clean logs."""
from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from kukaid.diagnose.robot import diagnose_robot
from kukaid.identify.robot_fit import fit_robot
from kukaid.logs import AxisLog, write_hdf5
from kukaid.models.robot import RobotModel
from kukaid.models.robot_effects import gas_spring

from robot_sim_helpers import multisine, true_friction, true_parameters


@pytest.fixture(scope="module")
def kr6() -> RobotModel:
    return RobotModel("kr6-r700-sixx")


def _logs(kr6, effect=None, shifts=(-0.7, 0.0, 0.7), duration=12.0):
    """Three recordings, A2 moving about a different angle in each (so a leave-one-out fit must
    carry its terms to angles it did not see); the truth has ``effect`` or not."""
    pi = true_parameters(kr6, 1)
    fr = true_friction(6, 2)
    if effect == "payload":
        pi = pi.copy()
        pi[50] += 2.0          # 2 kg on the last link, 5 cm out along its x axis
        pi[51] += 0.1
    out = []
    mid = 0.5 * (kr6.lower[1] + kr6.upper[1])
    for k, sh in enumerate(shifts):
        t, q, qd, qdd = multisine(kr6, duration, 250.0, seed=20 + k)
        q[:, 1] = mid + sh + 0.35 * (q[:, 1] - mid)
        qd[:, 1] *= 0.35
        qdd[:, 1] *= 0.35
        tau = np.einsum("sjk,k->sj", kr6.regressor(q, qd, qdd), pi) + fr["Fc"] * np.sign(qd) + fr["Fv"] * qd + fr["offset"]
        if effect == "counterbalance":
            tau[:, 1] -= 6.0 * gas_spring(q[:, 1], -1.2, 0.5)       # about 5 N·m, 4 % of A2's gravity torque
        rng = np.random.default_rng(k)
        tau += 0.05 * rng.standard_normal(tau.shape)
        out.append(AxisLog(time=t, q=q + 1e-5 * rng.standard_normal(q.shape), tau=tau, axes=tuple(range(1, 7)),
                           attrs={"source_file": f"rec{k}.h5"}))
    return out


@pytest.fixture(scope="module")
def clean_fit(kr6):
    return fit_robot(_logs(kr6)[1:2], kr6)


def test_clean_logs_name_nothing(kr6, clean_fit):
    d = diagnose_robot(clean_fit, _logs(kr6), kr6)
    assert d.steps == [] and d.folds == "each recording left out in turn"
    assert {r["name"] for r in d.rejected} >= {"payload", "counterbalance@A2"}


def test_a_small_spring_the_file_took_in_is_not_named_as_a_large_counterbalance(kr6):
    """A 5 N·m spring (4 % of A2's gravity torque: under a counterbalance's plausible share) in logs
    whose A2 ranges do not overlap, the file fitted on the middle one (its spring and offset terms
    took the spring in): the held-out recordings lie at A2 angles no training fold saw. Named
    before with a 105 N·m geometry chosen on all samples (the held-out ones too) that bent A2's
    torque toward them; a counterbalance named now must be the size the logs have."""
    logs = _logs(kr6, "counterbalance")
    d = diagnose_robot(fit_robot(logs[1:2], kr6), logs, kr6)
    for st in d.steps:
        if st["name"] == "counterbalance@A2":
            assert st["params"]["peak_torque_Nm"] < 10.0, d.lines()


@pytest.fixture(scope="module", params=[1, pytest.param(4, marks=pytest.mark.slow)])
def payload_cli(request, kr6, clean_fit, tmp_path_factory):
    """The payload logs on disk and ``kukaid diagnose --params robot.json --log ... --json`` of them,
    run once: its output and the diagnosis it printed (the two tests below read the same one; each
    ran it again, in-process and twice through the CLI, 3 x 20 s). ``--max-steps 1`` in the default
    suite (the second round names nothing: the same figures, 8 s of CPU, not 15), diagnose's
    default (4) with -m slow."""
    import kukaid.diagnose.robot as robot_diagnosis
    from kukaid.params import save_robot_params
    from kukaid_cli.main import cli

    d = tmp_path_factory.mktemp("payload")
    pf = d / "robot.json"
    save_robot_params(pf, clean_fit)
    paths = []
    for k, lg in enumerate(_logs(kr6, "payload")):
        paths += ["--log", str(d / f"rec{k}.h5")]
        write_hdf5(lg, d / f"rec{k}.h5")
    made = []

    def kept(*args, **kwargs):
        made.append(real(*args, **kwargs))
        return made[-1]
    real = robot_diagnosis.diagnose_robot
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(robot_diagnosis, "diagnose_robot", kept)
        r = CliRunner().invoke(cli, ["diagnose", "--params", str(pf), *paths, "--json", "--max-steps",
                                     str(request.param)])
    assert r.exit_code == 0, r.output
    assert len(made) == 1
    return pf, paths, r, made[0]


def test_a_payload_at_the_flange_is_named_with_its_mass(payload_cli):
    d = payload_cli[3]
    assert [s["name"] for s in d.steps][:1] == ["payload"], d.lines()
    assert d.steps[0]["params"]["mass_kg"] == pytest.approx(2.0, rel=0.1)
    assert np.mean(d.after) < 0.5 * np.mean(d.before)


def test_cli_accepts_a_robot_parameter_file(payload_cli, tmp_path, monkeypatch):
    """The CLI's --json (the fixture's run: the diagnosis the CLI made), its text (the same diagnosis
    printed: the diagnosis itself is not made again) and a one-axis option refused."""
    import kukaid.diagnose.robot as robot_diagnosis
    from kukaid_cli.main import cli

    pf, paths, r, d = payload_cli
    assert json.loads(r.stdout)["steps"][0]["name"] == "payload"
    assert json.loads(r.stdout)["heldout_relative_error_after"] == pytest.approx(d.after, rel=1e-12)
    monkeypatch.setattr(robot_diagnosis, "diagnose_robot", lambda params, logs, robot=None, max_steps=3: d)
    r = CliRunner().invoke(cli, ["diagnose", "--params", str(pf), *paths])
    assert r.exit_code == 0, r.output
    assert "step 1: payload" in r.stdout and "held out: each recording left out in turn" in r.stdout
    r = CliRunner().invoke(cli, ["diagnose", "--params", str(pf), *paths, "--alpha", "0.05", "-o",
                                 str(tmp_path / "out.json")])
    assert r.exit_code == 2 and "does not apply to a robot parameter file" in r.output
    assert len(r.output.strip().splitlines()) == 1 and not (tmp_path / "out.json").exists()


def test_a_candidate_short_of_the_margin_says_from_which_error_the_drop_is_measured():
    """New-user trial 18: on the LWR4+ (fit lwr4_1, diagnose lwr4_2 and lwr4_3) diagnose printed
    "load_dependent_friction@A1: held-out error 26.14 -> 23.20 % (needs a 5 % drop); 24.08 % without the
    load ...": an 11 % drop said to fall short of 5 %.  The drop is measured from the candidate without
    what names it (24.08 %, the same freedom); the reason now says so in the same sentence."""
    from kukaid.diagnose.robot import _short_of_margin

    why = _short_of_margin(0.2614, 0.2320, 0.2408, "the load (the gravity parameters as free)")
    assert why == ("held-out error 26.14 -> 23.20 % (needs a 5 % drop from 24.08 %, its error without the load "
                   "(the gravity parameters as free))")
    assert _short_of_margin(0.0150, 0.0201, 0.0150, "the ripple") == "held-out error 1.50 -> 2.01 % (needs a 5 % drop)"
