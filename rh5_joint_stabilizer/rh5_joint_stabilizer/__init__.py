"""rh5_joint_stabilizer."""
