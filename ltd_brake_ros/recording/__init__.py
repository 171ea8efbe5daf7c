"""MCAP recording in rosbag2 layout: writer, reader, recovery (see :mod:`.layout`)."""
