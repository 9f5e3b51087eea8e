"""Recording a run's raw bus traffic and clock readings, and replaying them to the drivers.

``imuhal run --record FILE`` writes a recording (format: docs/recording.md); ``imuhal replay
FILE`` feeds it back through :class:`~imuhal.offline.replay.ReplayBus` and
:class:`~imuhal.offline.replay.ReplayClock`, so the same drivers and estimators produce the
same floats, or stop at the first transaction that differs.
"""
