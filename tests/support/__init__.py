"""Test-only helpers shared by the core test areas."""
