"""sideslip_sim: 14-DOF vehicle model with Magic Formula tyres, manoeuvres, sensor noise,
and the labelled-bag generator. The physics core never imports rclpy; only node.py does."""

__version__ = "0.1.0"
