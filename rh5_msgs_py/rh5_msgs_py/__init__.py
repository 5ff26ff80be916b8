"""rh5_msgs_py: the interface contract shared by all nodes of the RH5 control suite."""
