#include "sparse_nav/ros/node_utils.h"

#include <cctype>

namespace sparse_nav
{
void loadParam(const ros::NodeHandle& pnh, const std::string& name, std::size_t& value)
{
  int v = static_cast<int>(value);
  pnh.param(name, v, v);
  value = v < 0 ? 0 : static_cast<std::size_t>(v);
}

void publishDiagnostics(ros::Publisher& pub, const std::string& name, bool ok, const std::string& message,
                        const std::map<std::string, std::string>& values)
{
  diagnostic_msgs::DiagnosticArray array;
  array.header.stamp = ros::Time::now();
  diagnostic_msgs::DiagnosticStatus status;
  status.name = name;
  status.hardware_id = "sparse_nav";
  status.level = ok ? diagnostic_msgs::DiagnosticStatus::OK : diagnostic_msgs::DiagnosticStatus::WARN;
  status.message = message;
  for (const auto& kv : values)
  {
    diagnostic_msgs::KeyValue entry;
    entry.key = kv.first;
    entry.value = kv.second;
    status.values.push_back(entry);
  }
  array.status.push_back(status);
  pub.publish(array);
}

bool lookupOrigin(const tf2_ros::Buffer& buffer, const std::string& fixed_frame, const std::string& frame,
                  const ros::Time& stamp, Eigen::Vector3d& origin, std::string* error)
{
  try
  {
    const ros::Time when = buffer.canTransform(fixed_frame, frame, stamp, ros::Duration(0.05)) ? stamp : ros::Time(0);
    const auto t = buffer.lookupTransform(fixed_frame, frame, when).transform.translation;
    origin = Eigen::Vector3d(t.x, t.y, t.z);
    return true;
  }
  catch (const tf2::TransformException& e)
  {
    if (error)
      *error = e.what();
    return false;
  }
}

bool isValidMapName(const std::string& name)
{
  if (name.empty() || name.size() > 64)
    return false;
  for (char c : name)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-'))
      return false;
  return true;
}
}  // namespace sparse_nav
