"""sideslip_sim: 14-DOF vehicle model with Magic Formula tyres, manoeuvres, sensor noise,
and the labelled-bag generator. The physics core never imports rclpy; only node.py does."""

from sideslip_sim import _numba_cache

_numba_cache.configure()

__version__ = "0.1.0"
