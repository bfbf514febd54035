"""sim_bridge package."""
