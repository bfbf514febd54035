"""push_planner package."""
