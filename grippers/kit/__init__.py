"""The backend kit: what every family needs and a plugin should not rewrite (docs/backends.md)."""
