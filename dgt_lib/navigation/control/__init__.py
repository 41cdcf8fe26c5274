"""Controller Integration (paper): tracking a planned path with MPPI.

``mppi_config`` (the controller's settings and the vehicle footprint it checks),
``bicycle`` (the kinematic bicycle: MPPI's twist → a steering angle, path resampling),
``mppi`` (the sampling controller, plain numpy), ``mppi_compiled`` (its per-sample loops in
numba, the same commands to the bit) and ``pure_pursuit`` (the ground-truth drives'
tracker). The speed loop that turns a commanded speed into wheel torque is part of the
simulated vehicle (``dgt_lib.world.speed_control``).
"""
