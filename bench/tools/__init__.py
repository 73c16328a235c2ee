"""Benchmark helpers that run ROS 2 nodes (rclpy users, like the packages' node modules)."""
