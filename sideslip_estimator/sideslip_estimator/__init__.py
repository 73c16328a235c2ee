"""sideslip_estimator: sample alignment, sliding window, model back-ends and the
estimator node. The runtime lands with the ROS 2 runtime issue; rclpy will be used
by node.py only."""

__version__ = "0.1.0"
