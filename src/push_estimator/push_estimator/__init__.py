"""push_estimator package."""
