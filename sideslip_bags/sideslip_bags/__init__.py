"""sideslip_bags: record and replay bags of the contract topics without the ROS 2 CLI.

``sideslip-record`` (:mod:`.record`) subscribes to the contract topics as their
publishers appear, with the QoS they offer, and writes every serialised message it
receives into a rosbag2 MCAP directory, like ``ros2 bag record -s mcap``.
``sideslip-play`` (:mod:`.play`) publishes a bag's raw messages again on an absolute
schedule, like ``ros2 bag play``. ``sideslip-record --reindex`` (:mod:`.reindex`)
finishes a bag whose recorder was killed, like ``ros2 bag reindex``.

Only ``record.py`` and ``play.py`` import rclpy; the helpers (offered QoS and its
adaptation, the playback plan (its schedule is sideslip_msgs_py.schedule, shared
with the simulator node), command-line options, message types, bag
reading and writing, metadata.yaml, MCAP scanning, reindexing) are plain Python and are
tested without DDS.
"""

__version__ = "0.1.0"
