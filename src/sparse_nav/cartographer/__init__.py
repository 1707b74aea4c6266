"""Cartographer core (ROS-free): map fragments per SLAM map, stored atomically with a checksum."""
from sparse_nav.cartographer.cartographer import (Cartographer, CartographerConfig, Fragment,
                                                  auto_name, voxel_unique)
from sparse_nav.cartographer.store import (FragmentError, FragmentStore, decode, encode,
                                           validate_name)

__all__ = ["Cartographer", "CartographerConfig", "Fragment", "FragmentError", "FragmentStore",
           "auto_name", "decode", "encode", "validate_name", "voxel_unique"]
