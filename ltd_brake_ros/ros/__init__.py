"""The ROS 2 adapters (the only modules that import rclpy): sim_node and replay_node."""
