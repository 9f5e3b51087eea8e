"""The "vqf" estimator: Laidig and Seel's VQF (the maintained ``vqf`` package) as a plugin."""
