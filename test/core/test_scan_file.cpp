#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "sparse_nav/core/line_features.h"
#include "sparse_nav/core/scan_file.h"

using sparse_nav::LineFeatureExtractor;
using sparse_nav::readScanFile;
using sparse_nav::ScanFileResult;

namespace
{
std::string fixture(const std::string& name)
{
  return std::string(SPARSE_NAV_FIXTURES) + "/laser/" + name;
}
}  // namespace

// room.log: a 6 m x 4 m room, robot at (0, 0.5) facing +x, a 0.9 m door in the wall 4 m ahead
// (y from 0.3 to 1.2 in the world, -0.2 to 0.7 in the scan), a wall 7 m ahead behind the door.
TEST(ScanFile, CarmenFlaserLinesAndTheirPoses)
{
  const ScanFileResult r = readScanFile(fixture("room.log"));
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.format, "carmen");
  ASSERT_EQ(r.scans.size(), 2u);
  EXPECT_EQ(r.n_bad_lines, 2u);  // a truncated FLASER and one with a non-number
  EXPECT_NE(r.first_bad_line.find("line 6"), std::string::npos) << r.first_bad_line;
  const auto& s = r.scans[0];
  EXPECT_EQ(s.scan.ranges.size(), 180u);
  EXPECT_NEAR(s.scan.angle_min_rad, -M_PI / 2, 1e-12);
  EXPECT_NEAR(s.scan.angle_increment_rad, M_PI / 180, 1e-12);
  EXPECT_EQ(s.scan.check(), "");
  EXPECT_TRUE(s.has_pose);
  EXPECT_NEAR(r.scans[1].pose.x_m, 0.2, 1e-12);
  EXPECT_NEAR(r.scans[1].pose.yaw_rad, 0.05, 1e-12);

  const auto f = LineFeatureExtractor().extract(s.scan);
  ASSERT_TRUE(f.ok) << f.reason;
  ASSERT_EQ(f.doors.size(), 1u);
  EXPECT_LT((f.doors[0].center() - Eigen::Vector2d(4.0, 0.25)).norm(), 0.05);
  EXPECT_EQ(f.corners.size(), 2u);
}

TEST(ScanFile, GzipGivesTheSameScans)
{
  const ScanFileResult plain = readScanFile(fixture("room.log"));
  const ScanFileResult gz = readScanFile(fixture("room.log.gz"));
  ASSERT_TRUE(gz.ok) << gz.error;
  ASSERT_EQ(gz.scans.size(), plain.scans.size());
  EXPECT_EQ(gz.scans[1].scan.ranges, plain.scans[1].scan.ranges);
}

TEST(ScanFile, RobotLaserLine)
{
  const ScanFileResult r = readScanFile(fixture("robotlaser.log"));
  ASSERT_TRUE(r.ok) << r.error;
  ASSERT_EQ(r.scans.size(), 1u);
  EXPECT_EQ(r.scans[0].scan.ranges.size(), 361u);
  EXPECT_NEAR(r.scans[0].scan.range_max_m, 30.0, 1e-9);
  EXPECT_EQ(r.scans[0].scan.check(), "");
  EXPECT_NEAR(r.scans[0].pose.y_m, 0.5, 1e-12);
}

TEST(ScanFile, CsvRowsIncludingBadOnes)
{
  const ScanFileResult r = readScanFile(fixture("scans.csv"));
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.format, "csv");
  ASSERT_EQ(r.scans.size(), 3u);
  const LineFeatureExtractor ex;
  const auto good = ex.extract(r.scans[0].scan);
  EXPECT_TRUE(good.ok) << good.reason;
  EXPECT_EQ(good.doors.size(), 1u);
  const auto mismatched = ex.extract(r.scans[1].scan);
  EXPECT_FALSE(mismatched.ok);
  EXPECT_TRUE(mismatched.walls.empty());
  EXPECT_FALSE(r.scans[2].has_pose);
  const auto nan = ex.extract(r.scans[2].scan);
  EXPECT_FALSE(nan.ok);
  EXPECT_NE(nan.reason.find("no valid return"), std::string::npos);
}

TEST(ScanFile, MissingCorruptAndEmptyInputAreRefused)
{
  ScanFileResult r = readScanFile(fixture("does_not_exist.log"));
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("cannot open"), std::string::npos) << r.error;
  r = readScanFile(fixture("corrupt.log"));
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("not a text file"), std::string::npos) << r.error;
  r = sparse_nav::parseScanText("PARAM a b\nODOM 1 2 3\n", "carmen");
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("no readable FLASER"), std::string::npos);
  r = sparse_nav::parseScanText("FLASER 1000000000 1 2 3\n", "carmen");
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.n_bad_lines, 1u);
  r = sparse_nav::parseScanText("1,2,3\n", "csv");
  EXPECT_FALSE(r.ok);
  r = sparse_nav::parseScanText("", "bag");
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("unknown format"), std::string::npos);
}
