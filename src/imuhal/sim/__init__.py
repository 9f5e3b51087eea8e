"""The simulated world: scenarios with ground truth that drive the chip emulators."""
