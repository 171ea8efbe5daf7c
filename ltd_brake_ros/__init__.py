"""ltd_brake_ros: freight-train emergency braking (UIC braked-weight method) as a ROS 2 plant."""

__version__ = "0.1.0"
