"""sideslip_msgs_py: the sideslip wire contract.

Topic names (:mod:`.topics`), QoS (:mod:`.qos`), every channel with its unit, topic and
message field (:mod:`.channels`, the registry the rest derives from), what one sensor
step holds (:mod:`.sample`), how it maps onto standard ROS 2 messages
(:mod:`.messages`, with the vectorised CDR codec in :mod:`.cdr`) and bag I/O
(:mod:`.bag`). Importing the package
imports neither rclpy nor rosbags; the modules that need them import them lazily.
"""

from .sample import GroundTruth, SampleArrays, SensorNoiseSigma, VehicleSample

__all__ = ["GroundTruth", "SampleArrays", "SensorNoiseSigma", "VehicleSample"]
