"""The control stage: torque residual (eqs. 12-14), admittance (15-16), RBF damping (17-22), the loop."""
