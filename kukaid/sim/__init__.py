"""The virtual KR C4: one robot axis under the KR C4's position control, measured as a KRC does.

``SimConfig`` (truth, servo, sensors, environment; paper defaults), ``load_sim_config`` (JSON
overrides), ``VirtualKRC4`` (reset / follow / command / set_external_torque / advance / read / run),
hidden effects in :mod:`kukaid.sim.effects`.

The six-axis virtual KR C4 (a whole robot from its URDF, Pinocchio dynamics, a servo per axis) is
:mod:`kukaid.sim.robot_plant` (``RobotSimConfig``, ``VirtualRobotKRC4``) with its seeded truth in
:mod:`kukaid.sim.robot_truth`; imported on use (Pinocchio takes one to two seconds to load).
"""
from kukaid.sim.config import SimConfig, SimConfigError, load_sim_config, sim_config_from_dict, truth_params
from kukaid.sim.effects import EFFECTS, draw_effect
from kukaid.sim.krc4 import VirtualKRC4

__all__ = ["SimConfig", "SimConfigError", "load_sim_config", "sim_config_from_dict", "truth_params",
           "VirtualKRC4", "EFFECTS", "draw_effect"]
