"""ROS 2 outputs: sensor_msgs in an MCAP file (``imuhal run --mcap FILE``; docs/outputs.md).

``settings`` and ``messages`` need nothing beyond imuhal; ``mcap_sink`` needs the ``ros``
extra (``mcap``, ``mcap-ros2-support``), imported only when a sink is opened.
"""
