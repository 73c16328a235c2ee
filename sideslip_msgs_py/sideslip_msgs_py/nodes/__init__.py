"""rclpy plumbing shared by every node and tool (the only rclpy users in this package).

The rest of :mod:`sideslip_msgs_py` is plain data and imports without ROS; this
sub-package converts it into rclpy objects and runs nodes with clean signal handling.
"""
