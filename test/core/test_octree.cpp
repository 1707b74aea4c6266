#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <limits>
#include <random>
#include <fstream>
#include <stdexcept>
#include <string>
#include <unordered_set>
#include <unistd.h>

#include "sparse_nav/core/flat_key_set.h"
#include "sparse_nav/core/octree_map.h"
#include "synthetic.h"

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

/// FNV-1a of the tree's .bt file: its node structure and every node's state.
std::uint64_t treeHash(const OctreeMap& map)
{
  const std::string path = tempPath("hash.bt");
  EXPECT_TRUE(map.save(path).ok);
  std::ifstream in(path, std::ios::binary);
  std::uint64_t h = 1469598103934665603ULL;
  for (char c; in.get(c);)
  {
    h = (h ^ static_cast<unsigned char>(c)) * 1099511628211ULL;
  }
  std::remove(path.c_str());
  return h;
}

/// A noisy 6 m x 5 m room with outliers around it, as a SLAM map gives.
PointList noisyRoom()
{
  PointList pts = sparse_nav::test::makeRoom(6.0, 5.0, 0.9, 0.07, 0.02, 11);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> x(-1.0f, 7.0f), y(-1.0f, 6.0f), z(-0.5f, 2.6f);
  for (int i = 0; i < 400; ++i)
  {
    pts.emplace_back(x(rng), y(rng), z(rng));
  }
  return pts;
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

TEST(OctreeMap, InsertionsKeepTheTreesOfTheFirstImplementation)
{
  // Trees and counts that the straightforward implementation (per-ray hash sets, one sort per key
  // list) gave for these insertions; faster ones must give the same bits.
  struct Case
  {
    double free_factor;
    double max_range_m;
    bool two_cameras;
    bool far_wall;  // a wall 500 m away: the marks' box is too large to be dense
    std::uint64_t hash_first, hash_second;
    std::size_t rays_first, free_first, new_second, rays_second, free_second;
  };
  const Case cases[] = {
    { 4.0, -1.0, false, false, 0x82dab3463989d825ULL, 0x951163ba2dcac049ULL, 3640, 6500, 679, 618, 3845 },
    { 1.0, 3.0, true, false, 0x99fb3da52898e685ULL, 0xed7de7df093f235aULL, 12718, 276906, 679, 679, 38464 },
    { 2.0, -1.0, true, false, 0xefc928deeee4e622ULL, 0x7171fc5012310fb1ULL, 11006, 52147, 679, 666, 16215 },
    { 4.0, -1.0, false, true, 0xac25ebcc9a996e0cULL, 0xd40a6c3db2d0e04bULL, 3676, 41726, 702, 640, 32005 },
  };
  for (const Case& c : cases)
  {
    OctreeMapConfig cfg;
    cfg.free_space_resolution_m = cfg.resolution_m * c.free_factor;
    cfg.max_range_m = c.max_range_m;
    OctreeMap map(cfg);
    const std::vector<Eigen::Vector3d> cameras{ { 3.0, 2.5, 1.2 }, { 1.0, 1.0, 1.0 } };
    PointList pts = noisyRoom();
    for (const auto& p : c.far_wall ? wall() : PointList())
    {
      pts.push_back(p + Eigen::Vector3f(400.0f, 300.0f, 80.0f));
    }
    std::vector<std::size_t> origin(pts.size(), 0);
    for (std::size_t i = 0; c.two_cameras && i < pts.size(); i += 3)
    {
      origin[i] = 1;
    }
    const auto first = map.insert(pts, cameras, origin);
    const std::uint64_t hash_first = treeHash(map);
    // A local bundle adjustment: some points move, a few are new.
    std::mt19937 rng(3);
    std::normal_distribution<float> shift(0.0f, 0.05f);
    for (std::size_t i = 0; i < pts.size(); i += 17)
    {
      pts[i] += Eigen::Vector3f(shift(rng), shift(rng), shift(rng));
    }
    for (int i = 0; i < 30; ++i)
    {
      pts.emplace_back(2.0f + 0.03f * i, 1.5f, 0.8f);
      origin.push_back(0);
    }
    const auto second = map.insert(pts, cameras, origin);
    const std::uint64_t hash_second = treeHash(map);
    EXPECT_EQ(hash_first, c.hash_first) << c.free_factor;
    EXPECT_EQ(hash_second, c.hash_second) << c.free_factor;
    EXPECT_EQ(first.n_rays, c.rays_first);
    EXPECT_EQ(first.n_free_voxels, c.free_first);
    EXPECT_EQ(second.n_new_voxels, c.new_second);
    EXPECT_EQ(second.n_rays, c.rays_second);
    EXPECT_EQ(second.n_free_voxels, c.free_second);
  }
}

TEST(OctreeMap, BatchQueryGivesTheStateOfEachPosition)
{
  OctreeMap map;
  EXPECT_EQ(map.query(PointList{ { 1.0f, 1.0f, 1.0f } }), std::vector<VoxelState>{ VoxelState::kUnknown });
  PointList pts = noisyRoom();
  map.insert(pts, Eigen::Vector3d(3.0, 2.5, 1.2));
  // A point in known free space splits a free block: free, occupied and unknown leaves at every size.
  map.insert(PointList{ { 2.02f, 2.02f, 1.02f } }, Eigen::Vector3d(3.0, 2.5, 1.2));
  PointList positions;
  std::mt19937 rng(8);
  std::uniform_real_distribution<float> x(-1.5f, 7.5f), y(-1.5f, 6.5f), z(-1.0f, 3.0f);
  for (int i = 0; i < 20000; ++i)
  {
    positions.emplace_back(x(rng), y(rng), z(rng));
  }
  // The points themselves (occupied, often repeated keys), and positions no key holds.
  positions.insert(positions.end(), pts.begin(), pts.begin() + 2000);
  positions.emplace_back(2.02f, 2.02f, 1.02f);
  positions.emplace_back(1e9f, 0.0f, 0.0f);
  positions.emplace_back(std::numeric_limits<float>::quiet_NaN(), 0.0f, 0.0f);
  const std::vector<VoxelState> states = map.query(positions);
  ASSERT_EQ(states.size(), positions.size());
  std::size_t counts[3] = { 0, 0, 0 };
  for (std::size_t i = 0; i < positions.size(); ++i)
  {
    ASSERT_EQ(states[i], map.query(Eigen::Vector3d(positions[i].cast<double>()))) << i;
    ++counts[static_cast<int>(states[i])];
  }
  EXPECT_GT(counts[static_cast<int>(VoxelState::kUnknown)], 1000u);
  EXPECT_GT(counts[static_cast<int>(VoxelState::kFree)], 1000u);
  EXPECT_GT(counts[static_cast<int>(VoxelState::kOccupied)], 1000u);
}

TEST(OctreeMap, NewPointsWithTheRestHeldGiveTheTreeOfTheWholeCloud)
{
  // A second cloud where some points moved (some of them into space the first cloud's rays freed)
  // and new ones came: inserting only those, with the rest held, gives the tree of inserting it whole.
  const PointList first = noisyRoom();
  PointList fresh, held;
  std::mt19937 rng(12);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (std::size_t i = 0; i < first.size(); ++i)
  {
    if (u(rng) < 0.03f)
    {
      fresh.push_back(first[i] + Eigen::Vector3f(u(rng) - 0.5f, u(rng) - 0.5f, u(rng) - 0.5f) * 0.6f);
    }
    else
    {
      held.push_back(first[i]);
    }
  }
  for (int i = 0; i < 200; ++i)
  {
    fresh.emplace_back(0.5f + 5.0f * u(rng), 0.5f + 4.0f * u(rng), 0.2f + 2.0f * u(rng));
  }
  const std::vector<Eigen::Vector3d> cameras{ { 3.0, 2.5, 1.2 }, { 1.5, 1.0, 1.0 } };
  auto nearestOf = [&](const PointList& pts) {
    std::vector<std::size_t> nearest;
    for (const auto& p : pts)
    {
      nearest.push_back((p.cast<double>() - cameras[0]).norm() < (p.cast<double>() - cameras[1]).norm() ? 0 : 1);
    }
    return nearest;
  };
  PointList whole = held;
  whole.insert(whole.end(), fresh.begin(), fresh.end());
  OctreeMap a, b;
  a.insert(first, cameras, nearestOf(first));
  b.insert(first, cameras, nearestOf(first));
  const auto stats_a = a.insert(whole, cameras, nearestOf(whole));
  const auto stats_b = b.insert(fresh, cameras, nearestOf(fresh), &held);
  EXPECT_EQ(stats_a.n_new_voxels, stats_b.n_new_voxels);
  EXPECT_GT(stats_b.n_new_voxels, 100u);
  EXPECT_EQ(stats_a.n_free_voxels, stats_b.n_free_voxels);
  EXPECT_EQ(a.numLeafNodes(), b.numLeafNodes());
  PointList positions = whole;
  std::uniform_real_distribution<float> x(-1.5f, 7.5f), y(-1.5f, 6.5f), z(-1.0f, 3.0f);
  for (int i = 0; i < 20000; ++i)
  {
    positions.emplace_back(x(rng), y(rng), z(rng));
  }
  EXPECT_TRUE(a.query(positions) == b.query(positions));
  // Without the held points, their coarse voxels are not protected and the rays free some: the
  // held points are what makes the trees equal.
  OctreeMap c;
  c.insert(first, cameras, nearestOf(first));
  c.insert(fresh, cameras, nearestOf(fresh));
  EXPECT_FALSE(a.query(positions) == c.query(positions));
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

TEST(FlatKeySet, AgreesWithStdUnorderedSet)
{
  sparse_nav::FlatKeySet set;
  std::unordered_set<std::uint64_t> reference;
  std::mt19937_64 rng(9);
  set.prefetch(42);
  EXPECT_FALSE(set.contains(42));
  for (int i = 0; i < 20000; ++i)
  {
    // Few distinct keys, so that repeats are common, plus the largest storable key.
    const std::uint64_t key = i == 7 ? sparse_nav::FlatKeySet::kEmptyKey - 1 : rng() % 5000 * 0x10001ULL;
    set.prefetch(key ^ 1);  // a hint only: the set must not change
    EXPECT_EQ(set.insert(key), reference.insert(key).second) << i;
    if (i == 10000)
    {
      set.reserve(100000);  // a rehash keeps every key
    }
  }
  EXPECT_EQ(set.size(), reference.size());
  for (std::uint64_t key = 0; key < 5000 * 0x10001ULL; key += 0x10001ULL / 2)
  {
    EXPECT_EQ(set.contains(key), reference.count(key) == 1) << key;
  }
  set.clear();
  EXPECT_EQ(set.size(), 0u);
  EXPECT_FALSE(set.contains(0));
  EXPECT_TRUE(set.insert(0));
}
