#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <stdexcept>
#include <string>
#include <unistd.h>

#include "sparse_nav/core/octree_map.h"

using sparse_nav::IoStatus;
using sparse_nav::OctreeMap;
using sparse_nav::OctreeMapConfig;
using sparse_nav::PointList;
using sparse_nav::VoxelState;

namespace
{
/// A wall of points at x = 3 (y, z in [-0.5, 0.5]).
PointList wall()
{
  PointList pts;
  for (float y = -0.5f; y <= 0.5f; y += 0.05f)
  {
    for (float z = -0.5f; z <= 0.5f; z += 0.05f)
    {
      pts.emplace_back(3.0f, y, z);
    }
  }
  return pts;
}

std::string tempPath(const std::string& name)
{
  return "/tmp/sparse_nav_test_octree_" + std::to_string(::getpid()) + "_" + name;
}
}  // namespace

TEST(OctreeMap, RayCastMarksFreeSpaceBetweenCameraAndWall)
{
  OctreeMap map;
  const auto stats = map.insert(wall(), Eigen::Vector3d(0, 0, 0));
  EXPECT_EQ(stats.n_out_of_range, 0u);
  EXPECT_GT(stats.n_inserted, 0u);
  EXPECT_EQ(map.query(Eigen::Vector3d(1.5, 0.0, 0.0)), VoxelState::kFree);
  EXPECT_EQ(map.query(Eigen::Vector3d(0.6, 0.03, -0.03)), VoxelState::kFree);
  EXPECT_EQ(map.query(Eigen::Vector3d(3.0, 0.0, 0.0)), VoxelState::kOccupied);
  EXPECT_EQ(map.query(Eigen::Vector3d(4.0, 0.0, 0.0)), VoxelState::kUnknown);  // behind the wall
  EXPECT_EQ(map.query(Eigen::Vector3d(0.0, 3.0, 0.0)), VoxelState::kUnknown);  // never seen
  EXPECT_GT(map.occupiedCenters().size(), 100u);
}

TEST(OctreeMap, APointInKnownFreeSpaceSplitsTheFreeBlockAroundIt)
{
  // The first insertion leaves the space before the wall as large free leaves; a later point in
  // it must turn only its own voxel occupied, with its neighbours inside the split block still free.
  OctreeMap map;
  map.insert(wall(), Eigen::Vector3d(0, 0, 0));
  const std::size_t leaves_before = map.numLeafNodes();
  ASSERT_EQ(map.query(Eigen::Vector3d(1.52, 0.02, 0.02)), VoxelState::kFree);
  const auto stats = map.insert(PointList{ Eigen::Vector3f(1.52f, 0.02f, 0.02f) }, Eigen::Vector3d(0, 0, 0));
  EXPECT_EQ(stats.n_new_voxels, 1u);
  EXPECT_EQ(map.query(Eigen::Vector3d(1.52, 0.02, 0.02)), VoxelState::kOccupied);
  EXPECT_EQ(map.query(Eigen::Vector3d(1.57, 0.02, 0.02)), VoxelState::kFree);
  EXPECT_EQ(map.query(Eigen::Vector3d(1.52, 0.07, 0.07)), VoxelState::kFree);
  EXPECT_EQ(map.query(Eigen::Vector3d(0.6, 0.03, -0.03)), VoxelState::kFree);
  EXPECT_EQ(map.query(Eigen::Vector3d(3.0, 0.0, 0.0)), VoxelState::kOccupied);
  EXPECT_GT(map.numLeafNodes(), leaves_before);
}

TEST(OctreeMap, FreeColumnsInAHeightBand)
{
  OctreeMap map;
  map.insert(wall(), Eigen::Vector3d(0, 0, 0));
  // Grid 5 m x 2 m from (-0.5, -1) at 0.1 m.
  std::vector<std::uint8_t> free_mask;
  map.markFreeColumns(-0.5, -1.0, 0.1, 50, 20, -0.2, 0.2, free_mask);
  ASSERT_EQ(free_mask.size(), 1000u);
  auto at = [&](double x, double y) {
    const int c = static_cast<int>((x + 0.5) / 0.1), r = static_cast<int>((y + 1.0) / 0.1);
    return free_mask[static_cast<std::size_t>(r) * 50 + c];
  };
  EXPECT_EQ(at(1.5, 0.0), 1);
  EXPECT_EQ(at(3.02, 0.0), 0);  // the wall itself is occupied
  EXPECT_EQ(at(4.0, 0.0), 0);   // unknown behind it
}

TEST(OctreeMap, PointsOutsideTheKeyRangeAreDroppedAndCounted)
{
  OctreeMap map;
  const double limit = map.maxCoordinate();
  EXPECT_GT(limit, 1000.0);
  PointList pts{ { 1, 0, 0 }, { static_cast<float>(limit * 2), 0, 0 }, { 0, -1e9f, 0 },
                 { std::numeric_limits<float>::quiet_NaN(), 0, 0 } };
  const auto stats = map.insert(pts, Eigen::Vector3d::Zero());
  EXPECT_EQ(stats.n_inserted, 1u);
  EXPECT_EQ(stats.n_out_of_range, 3u);
  EXPECT_TRUE(stats.origin_ok);

  const auto bad_origin = map.insert(pts, Eigen::Vector3d(1e7, 0, 0));
  EXPECT_FALSE(bad_origin.origin_ok);
  EXPECT_EQ(bad_origin.n_inserted, 0u);
  EXPECT_EQ(map.query(Eigen::Vector3d(1e9, 0, 0)), VoxelState::kUnknown);
}

TEST(OctreeMap, SaveAndLoadRoundTrip)
{
  OctreeMap map;
  map.insert(wall(), Eigen::Vector3d(0, 0, 0));
  const std::string path = tempPath("roundtrip.bt");
  const IoStatus saved = map.save(path);
  ASSERT_TRUE(saved.ok) << saved.message;
  OctreeMap other;
  const IoStatus loaded = other.load(path);
  ASSERT_TRUE(loaded.ok) << loaded.message;
  EXPECT_EQ(other.query(Eigen::Vector3d(3.0, 0.0, 0.0)), VoxelState::kOccupied);
  EXPECT_EQ(other.query(Eigen::Vector3d(1.5, 0.0, 0.0)), VoxelState::kFree);
  std::remove(path.c_str());
}

TEST(OctreeMap, CorruptFilesAreRefusedAndTheTreeIsKept)
{
  OctreeMap map;
  map.insert(wall(), Eigen::Vector3d(0, 0, 0));
  const std::string good = tempPath("good.bt");
  ASSERT_TRUE(map.save(good).ok);
  std::string bytes;
  {
    std::ifstream in(good, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  const std::size_t data_at = bytes.find("\ndata\n") + 6;
  ASSERT_GT(data_at, 6u);

  struct Case
  {
    std::string name;
    std::string content;
  };
  const std::string garbage_tree = bytes.substr(0, data_at) + std::string(4000, '\xff');
  const Case cases[] = {
    { "truncated", bytes.substr(0, data_at + (bytes.size() - data_at) / 2) },
    { "header only", bytes.substr(0, data_at) },
    { "garbage tree", garbage_tree },
    { "not octomap", "hello world\n" },
    { "empty", "" },
    { "bad size", [&] {
        std::string s = bytes;
        const auto p = s.find("size ");
        s.replace(p, s.find('\n', p) - p, "size 7");
        return s;
      }() },
  };
  for (const Case& c : cases)
  {
    const std::string path = tempPath("corrupt.bt");
    {
      std::ofstream out(path, std::ios::binary);
      out << c.content;
    }
    const IoStatus st = map.load(path);
    EXPECT_FALSE(st.ok) << c.name;
    EXPECT_FALSE(st.message.empty()) << c.name;
    EXPECT_NE(st.message.find(path), std::string::npos) << c.name << ": " << st.message;
    std::remove(path.c_str());
  }
  const IoStatus missing = map.load(tempPath("does_not_exist.bt"));
  EXPECT_FALSE(missing.ok);
  // The tree is unchanged after the failed loads.
  EXPECT_EQ(map.query(Eigen::Vector3d(3.0, 0.0, 0.0)), VoxelState::kOccupied);
  std::remove(good.c_str());
}

TEST(OctreeMap, ConfigValidation)
{
  OctreeMapConfig cfg;
  cfg.resolution_m = 0;
  EXPECT_THROW(OctreeMap{ cfg }, std::invalid_argument);
  cfg = OctreeMapConfig();
  cfg.prob_miss = 0.7;
  EXPECT_THROW(cfg.validate(), std::invalid_argument);
}
