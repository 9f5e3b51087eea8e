"""Chips bound to Linux kernel IIO drivers, read through the ``iio`` bus kind."""
