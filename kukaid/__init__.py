"""kukaid: identify the dynamics of a KUKA robot axis and push it by hand without a force sensor.

Implements Yao et al. 2018, "Sensorless and adaptive admittance control of industrial robot in
physical human-robot interaction".  Everything inside the library is SI (rad, rad/s, N·m, s).
"""

__version__ = "0.1.0"
