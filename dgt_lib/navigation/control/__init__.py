"""Controller Integration (paper): tracking a planned path with MPPI.

In the order of one MPPI iteration (:mod:`~dgt_lib.navigation.control.mppi`):

- ``mppi_config`` — the controller's settings (Nav2's, scaled to 5 m/s) and the vehicle
  footprint it checks;
- ``reference_path`` — the planner's path resampled, the progress along it;
- ``sampling`` — noisy control sequences around the warm start, the speed loop's lag;
- ``ancillary`` — biased sampling: a share of the samples around pure pursuit's rollout
  (``robust``'s, not the paper's);
- ``bicycle`` — the rollout kinematics, the bicycle relation twist → steering, the rear-axle
  pose, a kinematic plant to try a tracker without physics;
- ``critics`` — the cost terms, one named function each;
- ``mppi`` — the exponential weighting with temperature λ, the warm start, the controller;
- ``mppi_compiled`` — sampling, rollout and critics in numba, the same commands to the bit;
- ``pure_pursuit`` — the ground-truth drives' tracker (the same steering law as
  ``ancillary``'s rollout).

The speed loop that turns a commanded speed into wheel torque is part of the simulated
vehicle (``dgt_lib.world.speed_control``); the closed loop is ``dgt_lib.navigation.drive``.
"""
