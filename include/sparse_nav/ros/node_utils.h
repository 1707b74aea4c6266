#ifndef SPARSE_NAV_ROS_NODE_UTILS_H
#define SPARSE_NAV_ROS_NODE_UTILS_H

#include <cstdint>
#include <map>
#include <string>

#include <Eigen/Core>
#include <diagnostic_msgs/DiagnosticArray.h>
#include <ros/ros.h>
#include <tf2_ros/buffer.h>

namespace sparse_nav
{
/// @brief Reads a private parameter into `value`, keeping its current value (the Config default).
template <typename T>
void loadParam(const ros::NodeHandle& pnh, const std::string& name, T& value)
{
  pnh.param(name, value, value);
}

/// @brief As loadParam for a size_t, read through an int (the parameter server has no unsigned).
void loadParam(const ros::NodeHandle& pnh, const std::string& name, std::size_t& value);

/// @brief Publishes one DiagnosticStatus named `name` on /diagnostics.
void publishDiagnostics(ros::Publisher& pub, const std::string& name, bool ok, const std::string& message,
                        const std::map<std::string, std::string>& values);

/**
 * @brief Origin of `frame` in `fixed_frame` at `stamp`, or at the latest time TF has when the
 * stamp is not (yet) available. Returns false and sets `error` when there is no such transform.
 */
bool lookupOrigin(const tf2_ros::Buffer& buffer, const std::string& fixed_frame, const std::string& frame,
                  const ros::Time& stamp, Eigen::Vector3d& origin, std::string* error);

/**
 * @brief Tells when the SLAM map changes: a new map after a loss, or a merge back into an earlier
 * one (slam/state's map_index changes). Points and camera positions from before then are in another
 * map's anchoring, so maps built from them start afresh.
 */
class MapSwitchDetector
{
public:
  /// @brief True when map_index differs from the previous call's (never on the first call).
  bool switched(std::uint32_t map_index)
  {
    const bool changed = seen_ && map_index != index_;
    seen_ = true;
    index_ = map_index;
    return changed;
  }

private:
  bool seen_ = false;
  std::uint32_t index_ = 0;
};

/// @brief True for a map file name: 1-64 letters, digits, '_' or '-' (never a path).
bool isValidMapName(const std::string& name);
}  // namespace sparse_nav

#endif  // SPARSE_NAV_ROS_NODE_UTILS_H
