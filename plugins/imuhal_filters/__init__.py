"""Built-in estimators, each a plugin of its own."""
