"""The train's physics, free of ROS and files: equations, model families and the kernel.

Nothing here imports rclpy, mcap, matplotlib or argparse.
"""
from .equations import *  # noqa: F401,F403
from .equations import G, KMH_PER_MS, jit  # noqa: F401
