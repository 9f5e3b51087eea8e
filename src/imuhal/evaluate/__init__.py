"""Evaluating estimators against recordings with ground truth: ``imuhal evaluate``.

``recording`` reads BROAD trials (HDF5/MAT) and imuhal's own sample + truth CSVs into one
form; ``metrics`` computes BROAD's total/heading/inclination errors; ``runner`` runs jobs
(trial x estimator x setting) serially, ``dask_runner`` on a Dask cluster; ``report``
aggregates per trial, group and overall and writes the table, CSV and JSON.
"""
