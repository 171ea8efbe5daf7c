"""ROS-free plant runtime: pacing, jobs, lock-step, run policy, recorder lifecycle."""
