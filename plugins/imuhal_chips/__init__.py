"""Built-in chip drivers and their register-level emulators, each a plugin of its own."""
