"""The ROS 2 adapters (the only modules that import rclpy): sim_node and replay_node, and
`program`, what both programs do around their node (signals, arguments, one-line errors)."""
