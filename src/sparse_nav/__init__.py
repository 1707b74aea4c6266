"""sparse_nav: navigation from a monocular ORB-SLAM3 sparse point cloud.

The modules at this level are ROS-free and usable offline; ROS glue lives in ``sparse_nav.ros``.
"""
