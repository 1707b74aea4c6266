#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <string>
#include <unistd.h>

#include "sparse_nav/core/grid_pipeline.h"
#include "sparse_nav/core/point_file.h"
#include "synthetic.h"

using sparse_nav::GridPipeline;
using sparse_nav::GridPipelineConfig;
using sparse_nav::GridPipelineResult;
using sparse_nav::OccupancyGrid;
using sparse_nav::PointList;

namespace
{
/// The synthetic room tilted 5 deg, in a y-down SLAM frame, with the first camera (SLAM origin)
/// 1.1 m above the floor at the room centre; SLAM units are half metres (scale 2 m/unit).
PointList slamRoom(double tilt_deg = 5.0)
{
  const Eigen::Isometry3d tilt(Eigen::AngleAxisd(tilt_deg * M_PI / 180.0, Eigen::Vector3d::UnitX()));
  const Eigen::Isometry3d shift(Eigen::Translation3d(-2.5, -2.0, -1.1));
  PointList pts = sparse_nav::transformPoints(sparse_nav::test::makeRoom(), sparse_nav::test::zUpToYDown() * tilt * shift);
  for (auto& p : pts)
  {
    p *= 0.5f;
  }
  return pts;
}

std::int8_t valueAt(const OccupancyGrid& g, double x, double y)
{
  const int c = g.colOf(x), r = g.rowOf(y);
  if (c < 0 || r < 0 || c >= g.width || r >= g.height)
  {
    ADD_FAILURE() << "outside the grid: " << x << ", " << y;
    return OccupancyGrid::kUnknown;
  }
  return g.at(c, r);
}

std::string writeTemp(const std::string& name, const std::string& content)
{
  const std::string path = "/tmp/sparse_nav_test_pipeline_" + std::to_string(::getpid()) + "_" + name;
  std::ofstream out(path, std::ios::binary);
  out << content;
  return path;
}
}  // namespace

TEST(GridPipeline, SyntheticRoomGivesWallsFreeInsideAndAnOpenDoor)
{
  GridPipelineConfig cfg;
  cfg.metres_per_unit = 2.0;
  GridPipeline pipeline(cfg);
  const GridPipelineResult r = pipeline.process(slamRoom(), {});
  ASSERT_TRUE(r.ok) << r.status;
  ASSERT_TRUE(r.floor.found);
  EXPECT_NEAR(r.floor.plane.tilt_deg, 5.0, 0.5);
  EXPECT_GT(r.n_floor_band, 0u);
  EXPECT_GT(r.n_obstacles, 0u);
  for (const char* stage : { "guard", "density", "voxel", "floor", "align", "octree", "slice", "grid" })
  {
    EXPECT_EQ(r.stages_ms.count(stage), 1u) << stage;
  }
  EXPECT_GT(r.total_ms, 0.0);
  // The map frame keeps the heading but its origin is the floor point under the SLAM origin, so
  // locate the room by its walls: the room centre is at the camera's x-y.
  const Eigen::Vector3d cam = r.slam_to_map * Eigen::Vector3d::Zero();
  EXPECT_NEAR(cam.z(), 1.1, 0.05);
  const OccupancyGrid& g = pipeline.grid();
  EXPECT_EQ(valueAt(g, cam.x(), cam.y()), OccupancyGrid::kFree);
  EXPECT_EQ(valueAt(g, cam.x() + 1.5, cam.y() + 1.0), OccupancyGrid::kFree);
  // Walls at x = cam.x +- 2.5, y = cam.y +- 2.0 (the room is 5 m x 4 m), allowing tilt residue.
  auto occupiedNear = [&](double x, double y) {
    for (double dx = -0.1; dx <= 0.1; dx += 0.05)
      for (double dy = -0.1; dy <= 0.1; dy += 0.05)
        if (valueAt(g, x + dx, y + dy) == OccupancyGrid::kOccupied)
          return true;
    return false;
  };
  EXPECT_TRUE(occupiedNear(cam.x() + 2.5, cam.y()));
  EXPECT_TRUE(occupiedNear(cam.x() - 2.5, cam.y() + 1.0));
  EXPECT_TRUE(occupiedNear(cam.x(), cam.y() + 2.0));
  // The door: 0.9 m in the wall y = cam.y - 2 from x = cam.x - 1.5 to cam.x - 0.6.
  EXPECT_NE(valueAt(g, cam.x() - 1.05, cam.y() - 2.0), OccupancyGrid::kOccupied);
  EXPECT_EQ(valueAt(g, cam.x() + 1.0, cam.y() - 2.0) == OccupancyGrid::kOccupied ||
                valueAt(g, cam.x() + 1.0, cam.y() - 1.95) == OccupancyGrid::kOccupied,
            true);
  ASSERT_NE(pipeline.octree(), nullptr);
  EXPECT_GT(pipeline.octree()->numLeafNodes(), 0u);

  // A second call with the same points is an incremental no-op.
  const GridPipelineResult again = pipeline.process(slamRoom(), {});
  ASSERT_TRUE(again.ok) << again.status;
  EXPECT_FALSE(again.grid.full_rebuild);
  EXPECT_TRUE(again.grid.changed_tiles.empty());
}

TEST(GridPipeline, EmptyAndNonFiniteCloudsGiveAClearStatus)
{
  GridPipeline pipeline;
  const GridPipelineResult empty = pipeline.process(PointList(), {});
  EXPECT_FALSE(empty.ok);
  EXPECT_NE(empty.status.find("empty cloud"), std::string::npos) << empty.status;
  EXPECT_TRUE(pipeline.grid().empty());

  const float nan = std::numeric_limits<float>::quiet_NaN();
  const GridPipelineResult bad = pipeline.process(PointList{ { nan, 0, 0 }, { 1e9f, 0, 0 } }, {});
  EXPECT_FALSE(bad.ok);
  EXPECT_EQ(bad.guard.n_non_finite, 1u);
  EXPECT_EQ(bad.guard.n_out_of_range, 1u);
  EXPECT_NE(bad.status.find("empty cloud"), std::string::npos);
}

TEST(GridPipeline, TooTiltedFloorIsReportedNotGuessed)
{
  GridPipelineConfig cfg;
  cfg.metres_per_unit = 2.0;
  GridPipeline pipeline(cfg);
  const GridPipelineResult r = pipeline.process(slamRoom(25.0), {});
  EXPECT_FALSE(r.ok);
  EXPECT_FALSE(r.floor.found);
  EXPECT_NE(r.status.find("no floor plane"), std::string::npos) << r.status;
  EXPECT_TRUE(pipeline.grid().empty());
}

TEST(GridPipeline, ConfigValidation)
{
  GridPipelineConfig cfg;
  cfg.ground.ceiling_height_m = 0.1;
  EXPECT_THROW(GridPipeline{ cfg }, std::invalid_argument);
  cfg = GridPipelineConfig();
  cfg.metres_per_unit = 0;
  EXPECT_THROW(cfg.validate(), std::invalid_argument);
}

TEST(PointFile, TextWithExtraColumnsTrailingFieldsAndHeader)
{
  const std::string path = writeTemp("a.csv", "x,y,z\n1,2,3,,,\n4;5;6;7\n# comment\n\n7 8 9\n1,2,3,0.1,0.2\n");
  const auto r = sparse_nav::readPointFile(path);
  ASSERT_TRUE(r.ok) << r.error;
  ASSERT_EQ(r.points.size(), 4u);
  EXPECT_FLOAT_EQ(r.points[1].z(), 6.0f);
  EXPECT_FLOAT_EQ(r.points[2].x(), 7.0f);
  EXPECT_EQ(r.n_columns, 5u);
  std::remove(path.c_str());
}

TEST(PointFile, NonFiniteRowsAreDroppedAndAllNonFiniteIsAnError)
{
  const std::string some = writeTemp("some.csv", "1,2,3\nnan,1,1\n4,5,inf\n");
  const auto r = sparse_nav::readPointFile(some);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.points.size(), 1u);
  EXPECT_EQ(r.n_non_finite, 2u);
  const std::string all = writeTemp("all.csv", "nan,nan,nan\nnan,1,1\n");
  const auto bad = sparse_nav::readPointFile(all);
  EXPECT_FALSE(bad.ok);
  EXPECT_NE(bad.error.find("NaN"), std::string::npos) << bad.error;
  std::remove(some.c_str());
  std::remove(all.c_str());
}

TEST(PointFile, BadFilesGiveClearErrors)
{
  struct Case
  {
    const char* name;
    std::string content;
    const char* expect;
  };
  const Case cases[] = {
    { "empty.csv", "", "no points" },
    { "two.csv", "1,2\n3,4\n", "at least 3" },
    { "word.csv", "1,2,3\n1,abc,3\n", "not a number" },
    { "binary.bin", std::string("\x7f" "ELF\x02\x01\x01\0\0\0\0", 12) + std::string(100, '\0'), "not a point cloud" },
    { "fake.ply", "hello\n1 2 3\n", "not a ply file" },
    { "trunc.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 10\nproperty float x\nproperty float y\nproperty float z\nend_header\n\x01\x02",
      "truncated" },
    { "noxyz.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float a\nend_header\n1\n", "lacks x, y or z" },
  };
  for (const Case& c : cases)
  {
    const std::string path = writeTemp(c.name, c.content);
    const auto r = sparse_nav::readPointFile(path);
    EXPECT_FALSE(r.ok) << c.name;
    EXPECT_NE(r.error.find(c.expect), std::string::npos) << c.name << ": " << r.error;
    EXPECT_EQ(r.error.rfind(path, 0), 0u) << c.name << ": " << r.error;
    std::remove(path.c_str());
  }
  EXPECT_FALSE(sparse_nav::readPointFile("/nonexistent/dir/file.csv").ok);
}

TEST(PointFile, PlyAsciiAndBinaryAndPcd)
{
  const std::string ascii = writeTemp(
      "a.ply", "ply\nformat ascii 1.0\ncomment x\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\n"
               "property uchar red\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n1 2 3 255\n4 5 6 0\n");
  auto r = sparse_nav::readPointFile(ascii);
  ASSERT_TRUE(r.ok) << r.error;
  ASSERT_EQ(r.points.size(), 2u);
  EXPECT_FLOAT_EQ(r.points[1].y(), 5.0f);

  std::string bin = "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty double x\nproperty float y\n"
                    "property float z\nend_header\n";
  const double x0 = 1.5, x1 = -2.5;
  const float y0 = 2.0f, z0 = 3.0f, y1 = 4.0f, z1 = 5.0f;
  bin.append(reinterpret_cast<const char*>(&x0), 8).append(reinterpret_cast<const char*>(&y0), 4).append(reinterpret_cast<const char*>(&z0), 4);
  bin.append(reinterpret_cast<const char*>(&x1), 8).append(reinterpret_cast<const char*>(&y1), 4).append(reinterpret_cast<const char*>(&z1), 4);
  const std::string binary = writeTemp("b.ply", bin);
  r = sparse_nav::readPointFile(binary);
  ASSERT_TRUE(r.ok) << r.error;
  ASSERT_EQ(r.points.size(), 2u);
  EXPECT_FLOAT_EQ(r.points[1].x(), -2.5f);
  EXPECT_FLOAT_EQ(r.points[1].z(), 5.0f);

  const std::string pcd = writeTemp("c.pcd", "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
                                             "WIDTH 3\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n1 2 3\n4 5 6\n7 8 9\n");
  r = sparse_nav::readPointFile(pcd);
  ASSERT_TRUE(r.ok) << r.error;
  ASSERT_EQ(r.points.size(), 3u);
  EXPECT_EQ(r.format, "pcd");
  EXPECT_FLOAT_EQ(r.points[2].z(), 9.0f);
  std::remove(ascii.c_str());
  std::remove(binary.c_str());
  std::remove(pcd.c_str());
}
