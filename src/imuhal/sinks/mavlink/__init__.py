"""MAVLink to a ground station (``imuhal run --mavlink udpout:HOST:PORT``; docs/outputs.md).

``settings`` needs nothing beyond imuhal; ``sink`` needs the ``mavlink`` extra
(``pymavlink``), imported only when a sink is opened.
"""
