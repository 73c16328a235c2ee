"""Record and replay bags of the contract topics without the ROS 2 CLI.

``sideslip-record`` (:mod:`.record`) subscribes to the contract topics as their
publishers appear, with the QoS they offer, and writes every serialised message it
receives into a rosbag2 MCAP directory, like ``ros2 bag record -s mcap``.
``sideslip-play`` (:mod:`.play`) publishes a bag's raw messages again on an absolute
schedule, like ``ros2 bag play``. ``sideslip-record --reindex`` (:mod:`.reindex`)
finishes a bag whose recorder was killed, like ``ros2 bag reindex``.

Only ``record.py`` and ``play.py`` import rclpy; the helpers (QoS adaptation, the
playback schedule, argument parsing, bag reading and writing, metadata.yaml,
reindexing) are plain Python and are tested without DDS.
"""
