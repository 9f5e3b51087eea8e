"""Running estimators over logged samples (CSV) without a board: ``imuhal estimate``."""
