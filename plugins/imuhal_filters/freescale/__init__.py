"""freescale: port of the Freescale/NXP sensor fusion Kalman filters (build 422 fusion.c).

Modules: ``coords`` (NED / Android / Windows 8 orientation math), ``settings`` (timing and
fusion.h tuning), ``kalman`` (one Kalman step in reference units), ``batch`` (whole arrays),
``estimator`` (the ``freescale-9dof`` and ``freescale-6dof`` estimators), ``plugin``.
"""
