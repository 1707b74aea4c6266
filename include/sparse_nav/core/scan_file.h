#ifndef SPARSE_NAV_CORE_SCAN_FILE_H
#define SPARSE_NAV_CORE_SCAN_FILE_H

#include <cstddef>
#include <string>
#include <vector>

#include "sparse_nav/core/line_features.h"

namespace sparse_nav
{
/// @brief One scan read from a file, with the pose it was taken at when the file has one.
struct ScanRecord
{
  RangeScan scan;
  bool has_pose = false;
  Pose2D pose;               ///< scan pose in the file's world frame (CARMEN: corrected pose)
  std::size_t line = 0;      ///< 1-based line of the file
};

/// @brief Scans of a file, or why there are none.
struct ScanFileResult
{
  bool ok = false;
  std::string error;             ///< set when ok is false
  std::string format;            ///< "carmen" or "csv"
  std::vector<ScanRecord> scans;
  std::size_t n_bad_lines = 0;   ///< scan lines that could not be read (skipped)
  std::string first_bad_line;    ///< "line N: what" of the first one
};

/**
 * @brief Reads range scans from a CARMEN log or a CSV file, plain or gzip-compressed.
 *
 * CARMEN: FLASER lines (`FLASER n r1..rn x y theta odom_x odom_y odom_theta ...`, 180 degrees
 * from -90 degrees; n odd: the first and last beam at -90 and +90) and ROBOTLASER1 lines (start
 * angle, field of view, resolution and maximum range in the line; the laser pose is used). Other
 * lines are ignored.
 *
 * CSV: one scan per row, `angle_min_rad, angle_max_rad, angle_increment_rad, range_max_m, x_m,
 * y_m, yaw_rad, r0, r1, ...`; a pose of nan means none; ranges may be nan or inf; '#' starts a
 * comment line and a first row starting with a letter is a header.
 *
 * @param format "carmen", "csv", or "auto" (by the name: .csv is CSV, anything else CARMEN)
 */
ScanFileResult readScanFile(const std::string& path, const std::string& format = "auto");

/// @brief As readScanFile, for text already in memory.
ScanFileResult parseScanText(const std::string& text, const std::string& format);
}  // namespace sparse_nav

#endif  // SPARSE_NAV_CORE_SCAN_FILE_H
