"""The train's physics, free of ROS and files: equations, model families and the kernel.

``equations`` (train-level equations), ``brakes`` (brake models and the friction law),
``couplers`` (coupler models), ``kernel`` (the integrator), ``parameters`` (how model parameters
declare their units and ranges). Nothing here imports rclpy, mcap, matplotlib, argparse or yaml,
and nothing reads files.
"""
from .equations import *  # noqa: F401,F403
from .equations import G, KMH_PER_MS, jit  # noqa: F401
# Equations that moved into the model families, importable from here as before.
from .brakes.friction import (ARR_BG, ARR_BGU, BRAKE_BLOCKS, BRAKE_DISC,  # noqa: F401
                              BRAKE_NONE, block_force_factor, block_mu, braked_weight_t,
                              k_factor, karwatzki_mu, karwatzki_speed_factor,
                              sum_block_force_kN)
from .brakes.uic_empirical import rise_fraction  # noqa: F401
from .couplers.lut_hysteresis import coupler_force  # noqa: F401
