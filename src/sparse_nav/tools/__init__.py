"""Command-line tools of sparse_nav (ROS-free); each has a main() that a shim in scripts/ calls."""
