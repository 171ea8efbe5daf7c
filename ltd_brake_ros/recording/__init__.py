"""MCAP recording in rosbag2 layout: writer, reader, recovery (layout and modules: :mod:`.layout`)."""
