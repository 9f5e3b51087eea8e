"""The ``imuhal`` command line."""
