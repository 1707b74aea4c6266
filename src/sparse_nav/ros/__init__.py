"""ROS glue for sparse_nav: nodes, message conversions. Everything else stays ROS-free."""
