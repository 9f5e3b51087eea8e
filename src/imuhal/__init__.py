"""imuhal: orientation, altitude and climb rate from cheap IMU and barometer boards.

Units at every public boundary: m/s^2, rad/s, uT, Pa, degC, m, m/s; timestamps are int
nanoseconds. The default body frame is NED (x forward/north, y right/east, z down).
See docs/units-and-frames.md.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("imuhal")
except PackageNotFoundError:  # running from a source tree that was not installed
    __version__ = "0.0.0+unknown"

__all__ = ["__version__"]
