"""Calibration sessions: the applications that drive a pipeline through a calibration
procedure and store the result in a profile.

The procedures themselves (pure state machines over raw samples) and the stored models live
in :mod:`imuhal.calibration`, below the pipeline; this package is above it (and above
:mod:`imuhal.emulation`, to calibrate an emulated board). See docs/calibration.md.
"""
