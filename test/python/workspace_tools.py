"""Locates the package's C++ command-line tools in the sourced catkin workspace."""
import os


def find_tool(name):
    """Path of lib/sparse_nav/<name> under a CMAKE_PREFIX_PATH entry, or None when not built."""
    for prefix in os.environ.get("CMAKE_PREFIX_PATH", "").split(os.pathsep):
        path = os.path.join(prefix, "lib", "sparse_nav", name)
        if prefix and os.access(path, os.X_OK):
            return path
    return None
