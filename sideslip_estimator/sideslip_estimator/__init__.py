"""sideslip_estimator: sample alignment, sliding window, model back-ends and the
estimator node. The runtime lands with the ROS 2 runtime issue; only node.py will
import rclpy."""

__version__ = "0.1.0"
