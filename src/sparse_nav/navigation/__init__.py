"""Path planning and navigation (ROS-free): the navigator core, seed 001's RRT and map readers."""
