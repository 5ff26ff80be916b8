"""rh5_bringup."""
