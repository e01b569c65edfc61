"""Built-in device profiles (TOML). Installed as the data package ``grippers._profiles``."""
