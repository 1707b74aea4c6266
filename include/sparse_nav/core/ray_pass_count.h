#ifndef SPARSE_NAV_CORE_RAY_PASS_COUNT_H
#define SPARSE_NAV_CORE_RAY_PASS_COUNT_H

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include <Eigen/Core>

namespace sparse_nav
{
/// @brief Configuration of RayPassCount (GroundMapperConfig's clear_* values).
struct RayPassConfig
{
  double cell_m = 0.05;                   ///< x-y cell of the count [m]
  double height_tolerance_m = 0.4;        ///< rays this far below a cell's lowest point still count [m]
  double range_margin = 0.25;             ///< a ray counts where at least this fraction of it is ahead
  std::size_t max_cells = std::size_t{ 1 } << 25;  ///< larger candidate boxes are not counted
};

/// @brief A camera ray to a map point, in heights above the floor: camera index, end x-y [m], end height [m].
struct PassRay
{
  std::uint32_t camera = 0;
  Eigen::Vector2d end_xy = Eigen::Vector2d::Zero();
  double end_h = 0.0;
};

/// @brief All the rays, as a count and the ray at each index: a caller that holds the points
/// computes rays on demand rather than storing a copy of them (32 bytes per point).
struct PassRaySource
{
  std::size_t size = 0;
  std::function<PassRay(std::size_t)> at;

  /// @brief The rays of a list (which must outlive the source).
  static PassRaySource of(const std::vector<PassRay>& rays)
  {
    return PassRaySource{ rays.size(), [&rays](std::size_t i) { return rays[i]; } };
  }
};

/// @brief An obstacle candidate: x-y [m] and height above the floor [m].
struct PassCandidate
{
  Eigen::Vector2d xy = Eigen::Vector2d::Zero();
  double h = 0.0;
};

/**
 * @brief Per x-y cell holding obstacle candidates, how many camera rays pass through it below the
 * top of its candidates and at most height_tolerance_m under their bottom (GroundMapper's
 * clear_hit_min_rays rule), kept up to date as rays and candidates come and go.
 *
 * Rays are digital lines between cell centres (16.16 fixed point, one cell per step along the
 * major axis); a ray's end cell and the last range_margin of it do not count. build() walks every
 * ray. update() walks only the rays that came or went, and counts again from nothing the cells
 * whose candidates changed, finding the rays through such a cell in an index of each camera's
 * rays bucketed by direction: the rays through one cell lie within about one cell of its
 * direction. Either way the counts are those of a build() on the same rays and candidates.
 */
class RayPassCount
{
public:
  explicit RayPassCount(const RayPassConfig& config = RayPassConfig());

  /**
   * @brief Counts from nothing.
   * @return false, counting nothing, when the candidates span more than max_cells cells or lie
   *         beyond the fixed-point range (the count is then 0 everywhere)
   */
  bool build(const std::vector<Eigen::Vector2d>& camera_xy, const std::vector<double>& camera_h,
             const PassRaySource& rays, const std::vector<PassCandidate>& candidates);

  /**
   * @brief Applies the rays and candidates that went and came since the last build() or update().
   * Cameras must be the same. Falls back to build(camera_xy, camera_h, rays, candidates), the
   * full current sets, when a new candidate lies outside the counted box or the index grew stale.
   * @return what build() would return
   */
  bool update(const std::vector<Eigen::Vector2d>& camera_xy, const std::vector<double>& camera_h,
              const std::vector<PassRay>& removed_rays, const std::vector<PassRay>& added_rays,
              const std::vector<PassCandidate>& removed_candidates, const std::vector<PassCandidate>& added_candidates,
              const PassRaySource& rays, const std::vector<PassCandidate>& candidates);

  /// @brief Rays counted at the cell of xy (0 outside the box or without candidates there).
  std::uint32_t count(const Eigen::Vector2d& xy) const;
  /// @brief Whether the last call was a build() (also when update() fell back to one).
  bool lastWasBuild() const { return last_was_build_; }
  /// @brief Cells counted again from nothing by the last update().
  std::size_t numRecounted() const { return n_recounted_; }

private:
  struct IndexedRay
  {
    double h;
    std::uint32_t key;  // pseudo-angle of the ray's direction, quantised
    std::int32_t bx, by;  // end cell
    bool deleted;
  };
  /// A counted ray: camera, end cell (each coordinate offset by kCellOffset, x above y) and end height.
  struct End
  {
    std::uint64_t camera, cell;
    double h;
  };
  static constexpr int kCellOffset = 1 << 27;
  /// A cell of the box that held candidates: from the tolerance below its lowest candidate up to
  /// its highest (empty once they left), and the rays counted there.
  struct CandidateCell
  {
    float z_lo, z_hi;
    std::uint32_t count;
  };
  static constexpr std::uint32_t kNoCell = 0xffffffffu;
  struct CameraIndex
  {
    std::vector<std::uint32_t> start;  // per direction bucket (key >> kBucketShift), its first ray
    std::vector<IndexedRay> rays;      // by bucket, as of the last indexRays()
    std::vector<IndexedRay> added;     // by key, since then
    std::size_t n_deleted = 0;
  };
  static constexpr int kBucketShift = 20;  // 4096 direction buckets per camera

  // Cell indices stay within +-2^26, so that differences of them fit 16.16 fixed point in 64 bits.
  bool inReach(const Eigen::Vector2d& p) const
  {
    return p.allFinite() && std::abs(p.x() / config_.cell_m) < 67108864.0 && std::abs(p.y() / config_.cell_m) < 67108864.0;
  }
  Eigen::Vector2i cellOf(const Eigen::Vector2d& p) const
  {
    return Eigen::Vector2i(static_cast<int>(std::floor(p.x() / config_.cell_m)),
                           static_cast<int>(std::floor(p.y() / config_.cell_m)));
  }
  bool inBox(const Eigen::Vector2i& c) const
  {
    const Eigen::Vector2i d = c - lo_;
    return d.x() >= 0 && d.y() >= 0 && d.x() < size_.x() && d.y() < size_.y();
  }
  std::size_t index(const Eigen::Vector2i& c) const
  {
    return static_cast<std::size_t>(c.y() - lo_.y()) * static_cast<std::size_t>(size_.x()) +
           static_cast<std::size_t>(c.x() - lo_.x());
  }
  /// Whether the ray takes part: its camera and end are within reach.
  bool counts(const PassRay& r) const;
  /// Widens cell k's height range to hold a candidate at height h.
  void widen(std::size_t k, double h);
  /// The candidate cell of box cell k; nullptr when no candidate was in it since the last build().
  CandidateCell* candidateCell(std::size_t k) { return slot_[k] == kNoCell ? nullptr : &cells_[slot_[k]]; }
  const CandidateCell* candidateCell(std::size_t k) const { return slot_[k] == kNoCell ? nullptr : &cells_[slot_[k]]; }
  /// Whether box cell k holds candidates now (its height range is not empty).
  bool holdsCandidates(std::size_t k) const
  {
    const CandidateCell* c = candidateCell(k);
    return c && c->z_lo <= c->z_hi;
  }
  /// Whether the ray ends in its camera's cell: it passes nothing and is not indexed.
  bool inCameraCell(std::uint32_t camera, const IndexedRay& e) const;
  /// The block (with its margin) of cell k.
  std::size_t blockOf(std::size_t k) const;
  void setHot();
  /// Adds sign x (each ray of heights, from camera c to end cell b) to the counts of the cells it passes.
  void walk(std::size_t c, const Eigen::Vector2i& b, const std::vector<double>& heights, int sign);
  /// Whether the ray from camera cell a to end cell b visits cell k at a counted step; s is that step.
  bool visits(const Eigen::Vector2i& a, const Eigen::Vector2i& b, const Eigen::Vector2i& k, int& s) const;
  std::uint32_t recount(const Eigen::Vector2i& k) const;
  /// The ends of the counted rays, sorted by camera and end cell: the rays from one camera to one
  /// cell, which share their cells and differ only in height, are a run.
  std::vector<End> sortedEnds(const PassRaySource& rays) const;
  static Eigen::Vector2i endCell(const End& e);
  /// Makes the index from sortedEnds().
  void indexRays(const std::vector<End>& ends);
  IndexedRay indexed(const PassRay& ray) const;

  RayPassConfig config_;
  bool counted_ = false;
  bool last_was_build_ = true;
  std::size_t n_recounted_ = 0;
  std::vector<Eigen::Vector2d> camera_xy_;
  std::vector<double> camera_h_;
  std::vector<Eigen::Vector2i> camera_cell_;
  std::vector<char> camera_ok_;
  Eigen::Vector2i lo_ = Eigen::Vector2i::Zero(), size_ = Eigen::Vector2i::Zero();
  // Candidates occupy a tenth of the box's cells or fewer: per cell only its place among them.
  std::vector<std::uint32_t> slot_;       // per cell of the box: its place in cells_, or kNoCell
  std::vector<CandidateCell> cells_;
  int bw_ = 0, bh_ = 0;
  std::vector<std::uint32_t> block_cells_;  // candidate cells per block of 8 x 8
  std::vector<char> hot_;                    // a block or a neighbour holds a candidate cell
  std::vector<CameraIndex> index_;
};

}  // namespace sparse_nav

#endif  // SPARSE_NAV_CORE_RAY_PASS_COUNT_H
