"""One interface to a robot (:class:`Robot`: start, cycle, hold, close; samples out, commands in),
implemented by the virtual KR C4 (:class:`SimRobot`) and by a KR C4 over KUKAVARPROXY
(:class:`KvpRobot`)."""
from kukaid.robot.interface import Block, Robot, Sample
from kukaid.robot.kvp import KvpRobot
from kukaid.robot.sim import SimRobot

__all__ = ["Block", "KvpRobot", "Robot", "Sample", "SimRobot"]
