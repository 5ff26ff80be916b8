"""rh5_planner."""
