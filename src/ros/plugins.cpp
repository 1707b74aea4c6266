// Every nodelet of sparse_nav is registered here, once.
#include <pluginlib/class_list_macros.hpp>

#include "sparse_nav/ros/cloud_filter_nodelet.h"
#include "sparse_nav/ros/feature_extractor_nodelet.h"
#include "sparse_nav/ros/grid_builder_nodelet.h"
#include "sparse_nav/ros/ground_mapper_nodelet.h"

PLUGINLIB_EXPORT_CLASS(sparse_nav::CloudFilterNodelet, nodelet::Nodelet)
PLUGINLIB_EXPORT_CLASS(sparse_nav::GroundMapperNodelet, nodelet::Nodelet)
PLUGINLIB_EXPORT_CLASS(sparse_nav::GridBuilderNodelet, nodelet::Nodelet)
PLUGINLIB_EXPORT_CLASS(sparse_nav::FeatureExtractorNodelet, nodelet::Nodelet)
