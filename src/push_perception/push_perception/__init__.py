"""push_perception package."""
