"""push_core package."""
