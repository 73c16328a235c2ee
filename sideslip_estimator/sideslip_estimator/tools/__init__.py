"""Command-line tools of the estimator package (rclpy users, like node.py)."""
